"""The runs of a frequency sweep: one case per frequency (thesis Section 4.3).

* constant peak acceleration if the case gives ``loading.peak_acceleration`` (the amplitude
  follows, A = a_p / (2 pi f)^2: the thesis' Models II and III), else constant amplitude (Model I
  group 1 / 4);
* ``cycles`` from the case or ``--cycles``; run.duration = cycles / f + ``margin`` (default 1 s,
  as in the case files: free motion after the shaking);
* each point runs into DIR/f<frequency>Hz/ (``point_name``).

The command (dem_cli.commands.sweep) runs them through dem.batch; the analysis of each point and the
aggregate are postprocess.sweep's.
"""

from __future__ import annotations

import math

DEFAULT_MARGIN = 1.0


class SweepInputError(ValueError):
    """Bad sweep input (exit code 2); the message names the option or field."""


# the most frequencies a sweep takes unless told (--max-points): the thesis' sweeps have 5-19
# (1.8 - 3.6 Hz by 0.1 Hz), and one point of Model II is minutes to hours of CPU, so a hundred
# points is already a large study; beyond it a range is almost always a typo (1:1000:0.01 is
# 99 901 runs, 1.8:36:0.2 for 1.8:3.6:0.2 is 172)
MAX_SWEEP_POINTS = 100


def parse_frequencies(frequencies: str | None = None, rng: str | None = None,
                      max_points: int | None = None) -> list[float]:
    """Frequencies (Hz, sorted, unique) from "1.8,2.0,2.4" and/or "start:stop:step" (inclusive);
    more than ``max_points`` (default MAX_SWEEP_POINTS) refused, naming the count and the
    override."""
    limit = MAX_SWEEP_POINTS if max_points is None else max_points
    if limit < 1:
        raise SweepInputError(f"--max-points must be >= 1, got {limit}")
    out: list[float] = []
    if frequencies:
        for tok in frequencies.split(","):
            tok = tok.strip()
            if not tok:
                continue
            try:
                out.append(float(tok))
            except ValueError:
                raise SweepInputError(f"--frequencies: '{tok}' is not a number (Hz)") from None
    if rng:
        parts = rng.split(":")
        try:
            start, stop, step = (float(p) for p in parts)
        except ValueError:
            raise SweepInputError(f"--range: '{rng}' is not start:stop:step (Hz)") from None
        if not (step > 0) or stop < start:
            raise SweepInputError(f"--range: '{rng}' needs step > 0 and stop >= start")
        n = int(math.floor((stop - start) / step + 1e-6)) + 1
        if n > limit:
            raise SweepInputError(
                f"--range: '{rng}' gives {n:,} frequencies ({start:g} to {stop:g} Hz by "
                f"{step:g} Hz), more than {limit} (each one a run); check the range, or give "
                f"--max-points {n} if this is meant")
        out += [round(start + k * step, 9) for k in range(n)]
    if not out:
        raise SweepInputError("give the frequencies: --frequencies 1.8,2.0 and/or "
                              "--range 1.8:3.6:0.2")
    bad = [f for f in out if not (f > 0) or not math.isfinite(f)]
    if bad:
        raise SweepInputError(f"frequencies must be > 0 Hz, got {bad[0]}")
    freqs = sorted({round(f, 9) for f in out})
    if len(freqs) > limit:
        raise SweepInputError(f"{len(freqs):,} frequencies, more than {limit} (each one a run); "
                              f"give --max-points {len(freqs)} if this is meant")
    return freqs


def point_name(f: float) -> str:
    return f"f{f:.3f}Hz"


def sweep_cases(case, frequencies, cycles: float | None = None, margin: float = DEFAULT_MARGIN):
    """(name, Case) per frequency (module docstring); raises SweepInputError naming the field."""
    from pydantic import ValidationError

    from dem.case import Case, ShakeLoading, format_validation_error

    if not isinstance(case.loading, ShakeLoading):
        raise SweepInputError(f"loading.type: a sweep needs a 'shake' loading, got "
                              f"'{case.loading.type}'")
    if cycles is not None and not (cycles > 0):
        raise SweepInputError(f"--cycles must be > 0, got {cycles}")
    if not (margin >= 0):
        raise SweepInputError(f"--margin must be >= 0 s, got {margin}")
    out = []
    for f in frequencies:
        data = case.model_dump()
        ld = data["loading"]
        ld["frequency"] = float(f)
        if cycles is not None:
            ld["cycles"] = float(cycles)
        data["run"]["duration"] = ld["cycles"] / f + margin
        data["name"] = f"{case.name}-{point_name(f)}"
        try:
            out.append((point_name(f), Case.model_validate(data)))
        except ValidationError as err:
            raise SweepInputError(f"{point_name(f)}: "
                                  f"{format_validation_error(err, data=data)}") from None
    return out


class EnsembleInputError(ValueError):
    """Bad ensemble option (exit code 2); the message names it."""


def realisation_name(seed: int) -> str:
    return f"seed-{seed}"


def realisation_cases(case, realisations: int, seed: int | None):
    """(name, Case) for each realisation of an ensemble (dem ensemble, dem sweep
    --realisations): the case with imperfections.seed = seed + i (seed: the case's by default),
    named <case>-seed<seed>, run into seed-<seed>/."""
    if realisations is None or realisations < 1:
        raise EnsembleInputError(f"--realisations must be >= 1, got {realisations}")
    first = case.imperfections.seed if seed is None else seed
    if first < 0:
        raise EnsembleInputError(f"--seed must be >= 0, got {first}")
    out = []
    for s in range(first, first + realisations):
        data = case.model_dump()
        data["imperfections"]["seed"] = s
        data["name"] = f"{case.name}-seed{s}"
        out.append((realisation_name(s), type(case).model_validate(data)))
    return out
