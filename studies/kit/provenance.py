"""Where the code that ran and the inputs it read stand in git: a study writes these into its
records so that a result names the commit that reproduces it."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
#: the folders whose uncommitted changes make a result one that no commit reproduces
SOURCE_FOLDERS = ("dem", "dem_cli", "postprocess", "studies", "cases")


class NotInGit(ValueError):
    """A path that must be a committed file is not inside a git work tree."""


def git(cwd: Path, *args) -> subprocess.CompletedProcess:
    """``git -C cwd ARGS`` with its output captured (60 s timeout)."""
    return subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True,
                          timeout=60)


def content_commit(repo: Path, rel: str) -> str | None:
    """The last commit that changed the content of ``rel`` (following renames: a commit that only
    moved the file, git status R100, does not count), None when it was never committed.  A
    parameter set that moved to its study's folder keeps the commit that froze it."""
    res = git(repo, "log", "--follow", "-M", "--format=%x00%H", "--name-status", "--", rel)
    for entry in res.stdout.split("\x00")[1:]:
        lines = [ln for ln in entry.splitlines() if ln.strip()]
        if not lines:
            continue
        commit, status = lines[0].strip(), (lines[1].split("\t")[0] if len(lines) > 1 else "")
        if status != "R100":
            return commit
    return None


def git_state(path: Path) -> dict:
    """Where ``path`` stands in its git repository: {repo (top level), rel (path in it), tracked,
    modified (differs from HEAD: staged or not), commit (:func:`content_commit`)}.  Raises
    NotInGit when it is not inside a git work tree."""
    path = Path(path).resolve()
    top = git(path.parent, "rev-parse", "--show-toplevel")
    if top.returncode != 0:
        raise NotInGit(f"{path}: not inside a git repository (the freeze must be a commit)")
    repo = Path(top.stdout.strip())
    rel = str(path.relative_to(repo))
    tracked = git(repo, "ls-files", "--error-unmatch", "--", rel).returncode == 0
    status = git(repo, "status", "--porcelain", "--", rel).stdout.strip()
    return {"repo": str(repo), "rel": rel, "tracked": tracked, "modified": bool(status),
            "commit": content_commit(repo, rel) if tracked else None}


def source_state(checkout: bool = False) -> dict:
    """The code that ran: this checkout's HEAD and whether SOURCE_FOLDERS differ from it (a dirty
    tree: results that no commit reproduces); ``checkout``: also the checkout's path."""
    try:
        commit = git(ROOT, "rev-parse", "HEAD").stdout.strip() or None
        dirty = bool(git(ROOT, "status", "--porcelain", "--", *SOURCE_FOLDERS).stdout.strip()) \
            if commit else None
    except (OSError, subprocess.SubprocessError):
        commit, dirty = None, None
    out = {"commit": commit, "dirty": dirty}
    if checkout:
        out["checkout"] = str(ROOT)
    return out


def rel(path: Path) -> str:
    """A path relative to this checkout when inside it, else absolute."""
    path = Path(path).resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def repo_rel(path: Path) -> str:
    """A path relative to the git checkout that holds it (e.g. another checkout's results/),
    else as given."""
    path = Path(path).resolve()
    for parent in path.parents:
        if (parent / ".git").exists():
            return str(path.relative_to(parent))
    return str(path)


def utc_now(fmt: str = "%Y-%m-%dT%H:%M:%SZ") -> str:
    return time.strftime(fmt, time.gmtime())
