"""Samples of a motion as NumPy arrays, and their CSV form.

Frames and units: positions, velocities and accelerations of the tool in the world frame W
[m, m/s, m/s^2]; orientations as unit quaternions (w, x, y, z) from the tool frame to W;
joints in the model's order, joint 0 at the base [rad for revolute, m for prismatic; per s,
per s^2]; torques [N m, or N for a prismatic joint].
"""
import csv
import io
import os
from dataclasses import dataclass
from typing import IO, Iterable, List, Optional, Sequence, TextIO, Union

import numpy as np

from ._proto import pb

#: The CSV's first columns, in order; then q0.. (one per joint), tau0.. (one per joint, with
#: a model that has mass properties) and `step` (a sequence, or a path with an approach).
CSV_COLUMNS = ("t", "u", "s", "segment", "x", "y", "z", "qw", "qx", "qy", "qz",
               "vx", "vy", "vz", "ax", "ay", "az", "speed")


def has_steps(request: "pb.PlanRequest") -> bool:
    """Whether a request's samples come in steps, so that its CSV has a `step` column: a
    sequence, or a path with the approach move to its start (robot.approach)."""
    return len(request.sequence) > 0 or (request.HasField("robot") and request.robot.approach != 0)


def csv_header(joints: int, torques: int, steps: bool) -> List[str]:
    """The CSV header of samples with `joints` joints and `torques` torques."""
    return (list(CSV_COLUMNS) + [f"q{j}" for j in range(joints)] + [f"tau{j}" for j in range(torques)]
            + (["step"] if steps else []))


def csv_row(smp: "pb.Sample", steps: bool) -> list:
    """One sample's CSV row: floats as repr() writes them (they read back exactly)."""
    p, q, v, a = smp.position, smp.orientation, smp.velocity, smp.acceleration
    return ([repr(x) for x in (smp.t, smp.u, smp.s)] + [smp.segment]
            + [repr(x) for x in (p.x, p.y, p.z, q.w, q.x, q.y, q.z, v.x, v.y, v.z,
                                 a.x, a.y, a.z, smp.speed, *smp.joints, *smp.joint_torques)]
            + ([smp.step] if steps else []))


class CsvWriter:
    """Writes samples as CSV rows as they arrive (the header before the first row, from its
    number of joints and torques), so that a stream of any length is written without being
    held in memory."""

    def __init__(self, out: TextIO, steps: bool = False):
        self._writer = csv.writer(out)
        self.steps = steps
        self.count = 0
        self.header: Optional[List[str]] = None

    def write_samples(self, samples: Iterable["pb.Sample"]) -> None:
        for smp in samples:
            if self.header is None:
                self.header = csv_header(len(smp.joints), len(smp.joint_torques), self.steps)
                self._writer.writerow(self.header)
            self._writer.writerow(csv_row(smp, self.steps))
            self.count += 1

    def write_batch(self, batch: "pb.SampleBatch") -> None:
        self.write_samples(batch.samples)


def _vec(items, n):
    return np.array(items, dtype=float).reshape(-1, n)


@dataclass
class Samples:
    """The samples of a motion, one row per sample, N rows in time order.

    t: time from the start of the motion [s], (N,).
    u: the path parameter (the step's own in a sequence), (N,).
    s: arc length from the start of the path (the step's) [m], (N,).
    segment: the segment that holds u, (N,) int.
    step: the sequence step (0 without steps), (N,) int.
    position: tool position in W [m], (N, 3).
    orientation: tool orientation in W, unit quaternions (w, x, y, z), (N, 4).
    velocity, acceleration: of the tool in W [m/s, m/s^2], (N, 3).
    angular_velocity: of the tool in W [rad/s], (N, 3).
    speed: |velocity| [m/s], (N,).
    q, qd, qdd: joint positions, velocities, accelerations, (N, J); J = 0 without a robot.
    torques: joint torques [N m or N], (N, J) with a model that has mass properties, else (N, 0).
    plan_time, speed_factor: Execute's plan time [s] and speed factor, (N,); None elsewhere.
    steps: whether the motion comes in steps (the CSV's `step` column).
    """
    t: np.ndarray
    u: np.ndarray
    s: np.ndarray
    segment: np.ndarray
    step: np.ndarray
    position: np.ndarray
    orientation: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    angular_velocity: np.ndarray
    speed: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    torques: np.ndarray
    plan_time: Optional[np.ndarray] = None
    speed_factor: Optional[np.ndarray] = None
    steps: bool = False

    def __len__(self) -> int:
        return len(self.t)

    @property
    def joint_count(self) -> int:
        return self.q.shape[1]

    @property
    def duration(self) -> float:
        """Time from the first sample to the last [s] (0 for fewer than 2 samples)."""
        return float(self.t[-1] - self.t[0]) if len(self.t) > 1 else 0.0

    @classmethod
    def from_messages(cls, samples: Sequence["pb.Sample"], steps: bool = False) -> "Samples":
        """From geotraj.v1.Sample messages (the concatenated batches of a stream)."""
        n = len(samples)
        joints = len(samples[0].joints) if n else 0
        torques = len(samples[0].joint_torques) if n else 0
        for k, smp in enumerate(samples):
            if len(smp.joints) != joints or len(smp.joint_torques) != torques:
                raise ValueError(f"sample {k}: {len(smp.joints)} joints and {len(smp.joint_torques)} torques, "
                                 f"where sample 0 has {joints} and {torques}")
        live = n > 0 and samples[0].HasField("plan_time")
        return cls(
            t=np.array([x.t for x in samples], dtype=float),
            u=np.array([x.u for x in samples], dtype=float),
            s=np.array([x.s for x in samples], dtype=float),
            segment=np.array([x.segment for x in samples], dtype=np.int64),
            step=np.array([x.step for x in samples], dtype=np.int64),
            position=_vec([(x.position.x, x.position.y, x.position.z) for x in samples], 3),
            orientation=_vec([(x.orientation.w, x.orientation.x, x.orientation.y, x.orientation.z)
                              for x in samples], 4),
            velocity=_vec([(x.velocity.x, x.velocity.y, x.velocity.z) for x in samples], 3),
            acceleration=_vec([(x.acceleration.x, x.acceleration.y, x.acceleration.z) for x in samples], 3),
            angular_velocity=_vec([(x.angular_velocity.x, x.angular_velocity.y, x.angular_velocity.z)
                                   for x in samples], 3),
            speed=np.array([x.speed for x in samples], dtype=float),
            q=_vec([list(x.joints) for x in samples], joints) if joints else np.zeros((n, 0)),
            qd=_vec([list(x.joint_velocities) for x in samples], joints) if joints else np.zeros((n, 0)),
            qdd=_vec([list(x.joint_accelerations) for x in samples], joints) if joints else np.zeros((n, 0)),
            torques=_vec([list(x.joint_torques) for x in samples], torques) if torques else np.zeros((n, 0)),
            plan_time=np.array([x.plan_time for x in samples], dtype=float) if live else None,
            speed_factor=np.array([x.speed_factor for x in samples], dtype=float) if live else None,
            steps=steps)

    @classmethod
    def from_batches(cls, batches: Iterable["pb.SampleBatch"], steps: bool = False) -> "Samples":
        return cls.from_messages([smp for batch in batches for smp in batch.samples], steps)

    # --- CSV ---------------------------------------------------------------------------------

    def csv_header(self) -> List[str]:
        return csv_header(self.q.shape[1], self.torques.shape[1], self.steps)

    def write_csv(self, dest: Union[str, "os.PathLike[str]", IO[str]]) -> None:
        """The samples as CSV, one row each (columns: CSV_COLUMNS, then q0.., tau0.. and, with
        steps, `step`), floats written by repr() so that they read back exactly. `dest`: a
        path, or an open text file."""
        if isinstance(dest, (str, os.PathLike)):
            with open(dest, "w", newline="", encoding="utf-8") as out:
                self.write_csv(out)
            return
        w = csv.writer(dest)
        w.writerow(self.csv_header())
        n = len(self.t)
        floats = np.column_stack([self.t, self.u, self.s]).tolist()
        rest = np.column_stack([self.position, self.orientation, self.velocity, self.acceleration,
                                self.speed.reshape(n, 1), self.q, self.torques]).tolist()
        segment, step = self.segment.tolist(), self.step.tolist()
        for k in range(n):
            w.writerow([repr(x) for x in floats[k]] + [segment[k]] + [repr(x) for x in rest[k]]
                       + ([step[k]] if self.steps else []))

    @classmethod
    def read_csv(cls, src: Union[str, "os.PathLike[str]", IO[str]]) -> "Samples":
        """Samples from a CSV that write_csv (or geotraj_example.py) wrote. What the CSV does not
        hold (the angular velocity, joint velocities and accelerations) is NaN."""
        if isinstance(src, (str, os.PathLike)):
            with open(src, newline="", encoding="utf-8") as f:
                return cls.read_csv(f)
        reader = csv.reader(src)
        header = next(reader, None)
        if header is None:
            raise ValueError("an empty CSV: no header")
        if tuple(header[:len(CSV_COLUMNS)]) != CSV_COLUMNS:
            raise ValueError(f"not a samples CSV: its header starts {header[:len(CSV_COLUMNS)]}, "
                             f"expected {list(CSV_COLUMNS)}")
        extra = header[len(CSV_COLUMNS):]
        steps = bool(extra) and extra[-1] == "step"
        joint_cols = [c for c in extra if c.startswith("q")]
        torque_cols = [c for c in extra if c.startswith("tau")]
        if joint_cols != [f"q{j}" for j in range(len(joint_cols))] or \
                torque_cols != [f"tau{j}" for j in range(len(torque_cols))] or \
                len(joint_cols) + len(torque_cols) + steps != len(extra):
            raise ValueError(f"not a samples CSV: unexpected columns after `speed`: {extra}")
        rows = [r for r in reader if r]
        for k, r in enumerate(rows):
            if len(r) != len(header):
                raise ValueError(f"row {k + 1}: {len(r)} values for {len(header)} columns")
        data = np.array(rows, dtype=float).reshape(len(rows), len(header))
        n, j, tq = len(rows), len(joint_cols), len(torque_cols)
        col = {name: i for i, name in enumerate(header)}
        nan = np.full((n, 3), np.nan)
        base = len(CSV_COLUMNS)
        return cls(
            t=data[:, col["t"]], u=data[:, col["u"]], s=data[:, col["s"]],
            segment=data[:, col["segment"]].astype(np.int64),
            step=data[:, col["step"]].astype(np.int64) if steps else np.zeros(n, dtype=np.int64),
            position=data[:, [col["x"], col["y"], col["z"]]],
            orientation=data[:, [col["qw"], col["qx"], col["qy"], col["qz"]]],
            velocity=data[:, [col["vx"], col["vy"], col["vz"]]],
            acceleration=data[:, [col["ax"], col["ay"], col["az"]]],
            angular_velocity=nan, speed=data[:, col["speed"]],
            q=data[:, base:base + j], qd=np.full((n, j), np.nan), qdd=np.full((n, j), np.nan),
            torques=data[:, base + j:base + j + tq], steps=steps)

    def to_csv_string(self) -> str:
        out = io.StringIO()
        self.write_csv(out)
        return out.getvalue()
