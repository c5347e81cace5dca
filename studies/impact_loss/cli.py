"""The slenderness sweep of studies.impact_loss: r / r_Housner against h/b for each normal
dashpot, summary.json, impact-loss.png and the table (printed, and by ``--table`` from an
existing summary.json).

    python -m studies impact-loss --out results/impact-loss            # runs, JSON, plot, table
    python -m studies impact-loss --out results/impact-loss --table    # table and plot only
"""

from __future__ import annotations

import json
from pathlib import Path

import typer

from studies.impact_loss.runs import LAWS, material, rocking_block
from studies.kit import cli

SLENDERNESS = (2.0, 3.0, 4.0, 5.0, 6.0, 8.0)   # h/b
WIDTHS = (0.05, 0.2)   # m: the size check at h/b = 4 (the sweep's blocks are 0.1 m wide)
TARGET = (0.95, 0.97)  # r / r_H measured on concrete bases (ElGawady et al. 2011)
#: (h/b, r / r_H) of ElGawady et al.'s blocks on a concrete base (abstract of their chapter
#: "Effects of interface material on the dynamic behaviour of rigid blocks")
MEASURED = ((3.0, 0.97), (5.0, 0.95))
LABELS = {"critical": "critical: 0.5 of critical, released per point (today's default)",
          "pair": "pair: 0.75 of critical, the pair's no-tension rule",
          "stiffness": "stiffness: beta = 0.75 ms, the pair's rule"}

app = cli.study_app()


def _line(r: dict) -> str:
    return (f"{r['law']:9s} b {r['b_m']:.2f} m  h/b {r['h_over_b']:3.0f}  r/r_H "
            f"{[round(x, 4) for x in r['r_over_housner']]}  dt {r['dt_s']:.3g} s  "
            f"CPU {r['cpu_s']:.1f} s")


def sweep() -> dict:
    runs, sizes = [], []
    for law in LAWS:
        for hb in SLENDERNESS:
            r = rocking_block(hb, material(law))
            r["law"] = law
            runs.append(r)
            print(_line(r), flush=True)
        for b in WIDTHS:
            r = rocking_block(4.0, material(law), b=b, impacts=2)
            r["law"] = law
            sizes.append(r)
            print(_line(r), flush=True)
    return {"laws": LAWS, "target_r_over_housner": TARGET, "measured": MEASURED, "runs": runs,
            "sizes": sizes}


def table(summary: dict) -> str:
    loss = lambda r: (1 - r["r"][0]) / (1 - r["housner_r"])  # noqa: E731
    rows = {}
    for r in summary["runs"]:
        rows.setdefault(r["h_over_b"], {})[r["law"]] = r
    laws = list(summary["laws"])
    lines = ["| h/b | Housner r_H | " + " | ".join(f"{law}: r, **r/r_H**, loss/loss_H"
                                                     for law in laws)
             + " | dt (s): " + " / ".join(laws) + " |", "|---" * (len(laws) + 3) + "|"]
    for hb in sorted(rows):
        rr = rows[hb]
        lines.append(f"| {hb:g} | {rr[laws[0]]['housner_r']:.4f} | " + " | ".join(
            f"{rr[law]['r'][0]:.4f}, **{rr[law]['r_over_housner'][0]:.3f}**, {loss(rr[law]):.2f}"
            for law in laws) + " | " + " / ".join(f"{rr[law]['dt_s']:.3g}" for law in laws)
            + " |")
    lines += ["", "Size check, h/b = 4 (r / r_H of the first impact):", "",
              "| b (m) | " + " | ".join(laws) + " |", "|---" * (len(laws) + 1) + "|"]
    by_b = {}
    for r in summary["runs"]:
        if r["h_over_b"] == 4.0:
            by_b.setdefault(r["b_m"], {})[r["law"]] = r
    for r in summary["sizes"]:
        by_b.setdefault(r["b_m"], {})[r["law"]] = r
    for b in sorted(by_b):
        lines.append(f"| {b:g} | " + " | ".join(f"{by_b[b][law]['r_over_housner'][0]:.3f}"
                                                 for law in laws) + " |")
    return "\n".join(lines)


def plot(summary: dict, path: Path) -> None:
    from dem.output.plotting import agg_pyplot

    plt = agg_pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    lo, hi = summary["target_r_over_housner"]
    ax.axhspan(lo, hi, color="0.88", label="band aimed at (0.95-0.97)")
    ax.plot(*zip(*MEASURED), "k*", ms=11, label="measured, concrete base (ElGawady et al. 2011)")
    ax.axhline(1.0, color="k", lw=0.8)
    for law, mk in zip(summary["laws"], "osd"):
        lab = LABELS.get(law, law)
        rs = [r for r in summary["runs"] if r["law"] == law]
        ax.plot([r["h_over_b"] for r in rs], [r["r_over_housner"][0] for r in rs], mk + "-",
                label=lab)
    ax.set_xlabel("slenderness h/b")
    ax.set_ylabel("r / r_Housner (first impact)")
    ax.set_xlim(1.5, 8.5)
    ax.set_title("Free rocking from half the slenderness angle, b = 0.1 m, kn = 5e9 Pa/m",
                 fontsize=9)
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)


@app.command(help=cli.text(__doc__))
def run(out: Path = typer.Option(Path("results/impact-loss"), help="folder of summary.json, "
                                 "impact-loss.png"),
        table_only: bool = typer.Option(False, "--table", help="only the table and the plot, "
                                        "from an existing summary.json")) -> None:
    out.mkdir(parents=True, exist_ok=True)
    path = out / "summary.json"
    if table_only:  # the table, and the plot redrawn, from the summary
        summary = json.loads(path.read_text())
        plot(summary, out / "impact-loss.png")
        print(table(summary))
        return
    summary = sweep()
    path.write_text(json.dumps(summary, indent=1) + "\n")
    plot(summary, out / "impact-loss.png")
    print(table(summary))


def main(argv: list[str] | None = None) -> int:
    """``python -m studies impact-loss ARGV``; returns the exit code."""
    return cli.run(app, argv, "impact-loss")
