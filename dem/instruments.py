"""Virtual instruments: points fixed on blocks, sampled during the run (thesis Section 4.2.5).

An instrument is a point ``point`` (m, in the block's body frame) on block ``block``, with a
measuring direction ``direction`` (unit vector, table frame) and a kind: "transducer" (the thesis'
LVDTs bolted to the table: displacement relative to the table, ds) or "accelerometer" (absolute
acceleration, a).  Every instrument records all three components, so any direction can be
derived later; ``direction`` says what the physical instrument would read.

Recorded (``instruments.npz``), K samples every ``run.instrument_interval`` seconds:
    t            [K]        s
    disp         [K,n,3]    m      displacement of the point relative to the table (table frame)
    vel          [K,n,3]    m/s    velocity of the point relative to the table
    acc          [K,n,3]    m/s2   ABSOLUTE acceleration of the point, mean over the sample
                                   interval: (v_abs(t_k) - v_abs(t_k-1)) / dt_sample, with
                                   v_abs = v_rel + v_table (a band-limited reading, as a real
                                   accelerometer; the raw contact forces chatter at kHz)
    table_disp   [K,3], table_acc [K,3]   the excitation (table_acc: the mean over the sample
                                   interval, (v_table(t_k) - v_table(t_k-1)) / dt_sample)
    table_vel    [K,3]      m/s    the table's velocity at t_k (only where the loading asks for
                                   it: a lab or ramp start and a stepped shake, where the
                                   table's velocity is not the sine's; a default shake's
                                   instruments.npz keeps its fields)
    names [n], kind [n], block [n], point [n,3], direction [n,3], group [n] (block group name)

Thesis placement (Fig 4.4, Section 4.2.5), used for box models under shaking: all instruments on
the back walls L1 and T1 at the penultimate course (8th of 9, 14th of 15); for y excitation the
facade is L1 (out-of-plane, along y) and the side wall T1, for x excitation the other way round:
  transducers    ds-centre, ds-corner-a, ds-corner-b   on the facade (centre brick, both ends)
                 side-centre, side-corner-a, side-corner-b  on the side wall
  accelerometers a-centre, a-corner on the facade; a-corner-inplane on the facade's corner
                 brick along the wall; a-front-centre on the front facade (L2 / T2) centre.
Points are on the wall's outer face, at mid-height of the brick.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dem import quaternion
from dem.scene import Scene


@dataclass
class Instrument:
    name: str
    block: int
    point: np.ndarray      # body frame, m
    direction: np.ndarray  # table frame, unit
    kind: str              # "transducer" | "accelerometer"


def _outer_face_point(scene: Scene, b: int, outward: np.ndarray) -> np.ndarray:
    """Body-frame point at the centre of block b's face that points along ``outward``."""
    R = scene.rotation_matrices()[b]
    n_body = R.T @ outward
    k = int(np.argmax(np.abs(n_body)))
    p = np.zeros(3)
    p[k] = np.sign(n_body[k]) * 0.5 * scene.size[b, k]
    return p


def thesis_instruments(scene: Scene, axis: str) -> list[Instrument]:
    """Instruments of Fig 4.4 on a box model (groups L1, L2, T1, T2) for excitation along
    ``axis`` ("x" or "y"; "xy" for the diagonal tests gives both sets, prefixed x- and y-)."""
    if axis == "xy":
        return [Instrument(f"{a}-{i.name}", i.block, i.point, i.direction, i.kind)
                for a in ("x", "y") for i in thesis_instruments(scene, a)]
    names = list(scene.group_names)
    if not {"L1", "L2", "T1", "T2"} <= set(names):
        raise ValueError("thesis instruments need a box model (groups L1, L2, T1, T2)")
    facade, front, side = ("L1", "L2", "T1") if axis == "y" else ("T1", "T2", "L1")
    e = np.array([0.0, 1.0, 0.0]) if axis == "y" else np.array([1.0, 0.0, 0.0])
    along = np.array([1.0, 0.0, 0.0]) if axis == "y" else np.array([0.0, 1.0, 0.0])
    top = int(scene.course[scene.group == names.index(facade)].max())
    course = top - 1

    def pick(group: str, where: str) -> int:
        g = names.index(group)
        idx = np.flatnonzero((scene.group == g) & (scene.course == course))
        wall_along = np.array([1.0, 0.0, 0.0]) if group in ("L1", "L2") else \
            np.array([0.0, 1.0, 0.0])
        s = scene.position[idx] @ wall_along
        k = {"centre": np.argmin(np.abs(s)), "a": np.argmin(s), "b": np.argmax(s)}[where]
        return int(idx[k])

    def outward(group: str) -> np.ndarray:
        g = names.index(group)
        c = scene.position[scene.group == g].mean(axis=0)
        n = e if group in (facade, front) else along
        return n * np.sign(c @ n)

    out = []
    for nm, grp, where in (("ds-centre", facade, "centre"), ("ds-corner-a", facade, "a"),
                           ("ds-corner-b", facade, "b"), ("side-centre", side, "centre"),
                           ("side-corner-a", side, "a"), ("side-corner-b", side, "b")):
        b = pick(grp, where)
        n_out = outward(grp)
        out.append(Instrument(nm, b, _outer_face_point(scene, b, n_out), e.copy(), "transducer"))
    for nm, grp, where, d in (("a-centre", facade, "centre", e), ("a-corner", facade, "a", e),
                              ("a-corner-inplane", facade, "a", along),
                              ("a-front-centre", front, "centre", e)):
        b = pick(grp, where)
        out.append(Instrument(nm, b, _outer_face_point(scene, b, outward(grp)), d.copy(),
                              "accelerometer"))
    return out


class InstrumentRecorder:
    """Samples instruments from the engine state (see module docstring for the arrays).

    A sample is queued as it is taken (the blocks' states and the table's motion) and its
    arrays are computed when :attr:`rows` (or :attr:`last`) are read, for all
    the samples queued, in one pass of numpy calls: an engine of K scenes takes a sample of each
    every ~140 steps, and one sample's dozen small numpy calls (~0.1 ms of the host's time)
    cost more than a GPU's step of every scene.  The arithmetic is the per-sample arithmetic,
    element by element (each row's rotation, products and differences; the acceleration's
    difference with the sample before), so the rows are the same bit for bit however the
    samples are grouped (tests/test_instruments.py)."""

    def __init__(self, instruments: list[Instrument], scene: Scene,
                 table_velocity: bool = False):
        self.instruments = instruments
        self.blocks = np.array([i.block for i in instruments], dtype=int)
        self.points = np.array([i.point for i in instruments], dtype=float).reshape(-1, 3)
        q0 = scene.quat[self.blocks]
        self.R0 = quaternion.matrices(q0)
        self.x0 = scene.position[self.blocks] + np.einsum("nij,nj->ni", self.R0, self.points)
        self.group = [scene.group_names[scene.group[b]] for b in self.blocks]
        self._rows: dict[str, list] = {k: [] for k in ("t", "disp", "vel", "acc", "table_disp",
                                                        "table_acc")}
        if table_velocity:
            self._rows["table_vel"] = []
        self._prev = None  # (t, absolute velocity [n,3], table velocity [3]) of the last sample
        self._queued: list[tuple] = []  # samples taken, their rows not computed yet

    @property
    def rows(self) -> dict[str, list]:
        """The samples' arrays so far, one list entry a sample (the module docstring's keys)."""
        self._compute()
        return self._rows

    @property
    def last(self):
        """(t, absolute velocity [n,3], table velocity [3]) of the last sample, None before the
        first: the acceleration of the next one is the difference with it (a restart point
        keeps it: dem.run.resume)."""
        self._compute()
        return self._prev

    @last.setter
    def last(self, value) -> None:
        self._compute()
        self._prev = value

    def sample(self, t: float, pos, quat, vel, omega, table_disp, table_vel) -> None:
        """One sample at time t (s) from the state of every block (arrays indexed by block)
        and the table's displacement and velocity (m, m/s)."""
        b = self.blocks
        self.sample_blocks(t, pos[b], quat[b], vel[b], omega[b], table_disp, table_vel)

    def sample_blocks(self, t: float, pos, quat, vel, omega, table_disp, table_vel) -> None:
        """:meth:`sample` from the states of the instruments' own blocks ([n] rows, one per
        instrument, in the order of ``instruments``); ``table_disp`` / ``table_vel`` may also
        be a callable of an array of times (the loading's base_disp / base_vel), called for
        the queued samples at once.  The arrays are kept, not copied: the caller hands over
        arrays it does not write again."""
        self._queued.append((t, pos, quat, vel, omega, table_disp, table_vel))

    def _compute(self) -> None:
        """The queued samples' rows (class docstring)."""
        queued, self._queued = self._queued, []
        if not queued:
            return
        t = [s[0] for s in queued]
        pos, quat, vel, omega = (np.stack([s[i] for s in queued]) for i in range(1, 5))
        table_disp, table_vel = (self._table(queued, i) for i in (5, 6))
        R = quaternion.matrices(quat)                       # [m, n, 3, 3]
        r = np.einsum("mnij,nj->mni", R, self.points)
        x = pos + r
        v = vel + cross(omega, r)
        v_abs = v + table_vel[:, None, :]
        rows, prev = self._rows, self._prev
        for k in range(len(queued)):
            if prev is None:
                acc = np.zeros((len(self.blocks), 3))
                table_acc = np.zeros(3)
            else:
                dt = t[k] - prev[0]
                acc = (v_abs[k] - prev[1]) / dt
                table_acc = (table_vel[k] - prev[2]) / dt
            prev = (t[k], v_abs[k], table_vel[k])
            rows["t"].append(t[k])
            rows["disp"].append(x[k] - self.x0)
            rows["vel"].append(v[k])
            rows["acc"].append(acc)
            rows["table_disp"].append(table_disp[k])
            rows["table_acc"].append(table_acc)
            if "table_vel" in rows:
                rows["table_vel"].append(table_vel[k])
        self._prev = prev

    @staticmethod
    def _table(queued: list[tuple], i: int) -> np.ndarray:
        """[m, 3] the table's displacement (i = 5) or velocity (i = 6) of the queued samples:
        given, or a callable's values at their times (one call for each run of samples that
        share the callable)."""
        out = np.empty((len(queued), 3))
        k = 0
        while k < len(queued):
            f = queued[k][i]
            if not callable(f):
                out[k] = np.asarray(f, float)
                k += 1
                continue
            e = k + 1
            while e < len(queued) and callable(queued[e][i]) and queued[e][i] == f:
                e += 1
            out[k:e] = f(np.array([s[0] for s in queued[k:e]], dtype=float))
            k = e
        return out

    def arrays(self) -> dict[str, np.ndarray]:
        out = {k: np.asarray(v) for k, v in self.rows.items()}
        out.update({
            "names": np.array([i.name for i in self.instruments]),
            "kind": np.array([i.kind for i in self.instruments]),
            "block": self.blocks,
            "point": self.points,
            "direction": np.array([i.direction for i in self.instruments]).reshape(-1, 3),
            "group": np.array(self.group),
        })
        return out


def cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a x b over the last axis (3): numpy.cross's products and differences, in its order
    (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0: the same numbers), without its generic
    set-up (~30 us a call on small arrays)."""
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)
