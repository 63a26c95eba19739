"""A perception model between a state source and the corrector: the object's and the target's poses as a
real robot's perception reports them, centimetres off, late, sometimes missing.

    reported(t) = true(t - lag) + bias + noise(t)      bias: drawn once per episode, |bias| = bias_m, its
                                                       direction uniform in 3-D; noise: N(0, noise_m^2) per axis
    dropout: the pose is missing for runs of dropout_run steps, dropout of the steps in all; while it is,
    the last reported pose is held and pose_age grows (NaN, and missing_pose, before any was reported)

Each pose (object, target) has its own faults (`PoseFaults`); the packed state's other fields (the arm, the
gripper, the dynamics) pass unchanged, and `pose_age` becomes the older pose's age (lag + steps held). The
object's resting height (obj_rest_z, read at reset) takes the object's bias: what a stack that saw the object
at reset would report. Only the corrector reads the result: the policy keeps its own observation.

    perception = Perception(PerceptionConfig.both(bias_m=0.02, noise_m=0.01), batch_size=1)
    perception.reset(seed=7)                  # each episode; or let apply() see episode_step go back
    seen = perception.apply(flat)             # (B, L) packed states -> what the corrector is given
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

import numpy as np

from lerobot_physvla.core.state import field_offsets, n_joints_from_size


@dataclass(frozen=True)
class PoseFaults:
    """What perception does to one pose.

    Attributes:
        bias_m: a constant offset per episode, of this length (m), its direction drawn uniformly in 3-D.
        noise_m: per-step Gaussian noise, this standard deviation on each axis (m).
        lag_steps: the pose reported is this many control steps old.
        dropout: the fraction of steps the pose is missing (0 .. 1), in runs of `dropout_run` steps.
        dropout_run: the length of a dropout, control steps.
    """

    bias_m: float = 0.0
    noise_m: float = 0.0
    lag_steps: int = 0
    dropout: float = 0.0
    dropout_run: int = 5

    def __post_init__(self):
        if not (0.0 <= self.bias_m < np.inf and 0.0 <= self.noise_m < np.inf):
            raise ValueError(f"perception: bias_m and noise_m must be finite distances >= 0 (m), got {self.bias_m}, "
                             f"{self.noise_m}")
        if not (int(self.lag_steps) == self.lag_steps >= 0 and int(self.dropout_run) == self.dropout_run >= 1):
            raise ValueError(f"perception: lag_steps must be an int >= 0 and dropout_run an int >= 1, got "
                             f"{self.lag_steps}, {self.dropout_run}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"perception: dropout is a fraction of steps in [0, 1), got {self.dropout}")

    @property
    def exact(self) -> bool:
        return self.bias_m == self.noise_m == self.dropout == 0.0 and self.lag_steps == 0

    @property
    def error_bound_m(self) -> float:
        """bias + 2 sigma of the noise: a bound on |reported - true| for a static pose (m); what the
        corrector's pose_error_m is set to when it is told the truth."""
        return self.bias_m + 2.0 * self.noise_m


@dataclass(frozen=True)
class PerceptionConfig:
    """The faults on the object's pose and on the target's (`PoseFaults` each)."""

    object: PoseFaults = field(default_factory=PoseFaults)
    target: PoseFaults = field(default_factory=PoseFaults)

    @classmethod
    def both(cls, **faults) -> PerceptionConfig:
        """The same faults on the object's pose and the target's."""
        return cls(PoseFaults(**faults), PoseFaults(**faults))

    @classmethod
    def from_flags(cls, flags) -> PerceptionConfig:
        """The same faults on both poses from an object with pose_bias_m, pose_noise_m, pose_lag_steps and
        pose_dropout (the `--env.pose_*` / `--pose_*` flags)."""
        return cls.both(bias_m=flags.pose_bias_m, noise_m=flags.pose_noise_m, lag_steps=flags.pose_lag_steps,
                        dropout=flags.pose_dropout)

    @classmethod
    def from_dict(cls, d: dict) -> PerceptionConfig:
        """{"object": {...}, "target": {...}} (PoseFaults fields each), or PoseFaults fields for both;
        ValueError naming what is unknown."""
        d = dict(d or {})
        if set(d) <= {"object", "target"}:
            return cls(PoseFaults(**d.get("object", {})), PoseFaults(**d.get("target", {})))
        unknown = set(d) - set(PoseFaults.__dataclass_fields__)
        if unknown:
            raise ValueError(f"perception: unknown fault(s) {sorted(unknown)}; choose from "
                             f"{', '.join(PoseFaults.__dataclass_fields__)} (or object / target tables)")
        return cls.both(**d)

    def to_dict(self) -> dict:
        return {"object": asdict(self.object), "target": asdict(self.target)}

    @property
    def exact(self) -> bool:
        return self.object.exact and self.target.exact

    @property
    def error_bound_m(self) -> float:
        """The larger of the two poses' bounds (PoseFaults.error_bound_m), m."""
        return max(self.object.error_bound_m, self.target.error_bound_m)

    @property
    def bias_m(self) -> float:
        """The larger of the two poses' biases, m: what pose_error_m is told when pose_noise_m tells the noise."""
        return max(self.object.bias_m, self.target.bias_m)

    @property
    def noise_m(self) -> float:
        """The larger of the two poses' per-step noise sigmas, m: the truth for pose_noise_m."""
        return max(self.object.noise_m, self.target.noise_m)


_POSES = (("object", "obj_pos"), ("target", "target_pos"))


class Perception:
    """The perception model over B envs (module doc); per env its own random stream, history and dropouts.

    Attributes:
        config: the faults.
        counts: steps seen, steps with a pose missing (held or NaN), steps with no pose at all (NaN).
    """

    def __init__(self, config: PerceptionConfig, batch_size: int = 1, seed: int = 0):
        self.config, self.batch_size, self.seed = config, batch_size, seed
        self.counts = {"steps": 0, "held": 0, "missing": 0}
        self._last_step = np.full(batch_size, np.nan)
        self._env = [_EnvPerception() for _ in range(batch_size)]
        for i in range(batch_size):
            self._reset_env(i, seed * 1_000_003 + i)

    def reset(self, seed: int | None = None, env_ids=None) -> None:
        """Start new episodes (all envs, or env_ids): new biases and dropouts, the history forgotten. seed:
        the episode's seed (each env i draws from seed and i), else the next draw of the constructor's."""
        for i in range(self.batch_size) if env_ids is None else env_ids:
            self._reset_env(int(i), None if seed is None else seed * 1_000_003 + int(i))

    def _reset_env(self, i: int, seed: int | None) -> None:
        e = self._env[i]
        e.rng = np.random.default_rng(seed if seed is not None else e.rng.integers(2**63))
        e.bias = {name: _direction(e.rng) * getattr(self.config, name).bias_m for name, _ in _POSES}
        e.history = {name: [] for name, _ in _POSES}
        e.held = {name: None for name, _ in _POSES}
        e.age = {name: 0 for name, _ in _POSES}
        e.dropped = {name: 0 for name, _ in _POSES}
        self._last_step[i] = np.nan

    def apply(self, flat: np.ndarray) -> np.ndarray:
        """What the corrector is given for these (B, L) packed states (a new array; `flat` is not touched).
        An env whose episode_step went back starts a new episode (drawn from the running stream)."""
        flat = np.asarray(flat, dtype=np.float64)
        if flat.ndim != 2 or flat.shape[0] != self.batch_size:
            raise ValueError(f"perception: packed states must be ({self.batch_size}, L), got {flat.shape}")
        out = flat.copy()
        if self.config.exact:
            return out
        f = field_offsets(n_joints_from_size(flat.shape[1]))
        for i in range(self.batch_size):
            step = flat[i, f["episode_step"]]
            if step < self._last_step[i]:
                self._reset_env(i, None)
            self._last_step[i] = step
            if not flat[i, f["valid"]] > 0.5:
                continue  # an unread state stays what it is: the corrector passes through on it
            e, ages = self._env[i], []
            for name, key in _POSES:
                faults = getattr(self.config, name)
                true = flat[i, f[key] : f[key] + 3].copy()
                if name == "object":
                    true = np.append(true, flat[i, f["obj_rest_z"]])
                seen, age = e.report(name, true, faults)
                ages.append(age)
                self.counts["held"] += age > faults.lag_steps
                if seen is None:
                    self.counts["missing"] += 1
                    seen = np.full(true.shape, np.nan)
                out[i, f[key] : f[key] + 3] = seen[:3]
                if name == "object":
                    out[i, f["obj_rest_z"]] = seen[3]
            out[i, f["pose_age"]] = max(ages)
            self.counts["steps"] += 1
        return out


class _EnvPerception:
    """One env's draws and memory (Perception)."""

    rng: np.random.Generator

    def report(self, name: str, true: np.ndarray, faults: PoseFaults) -> tuple[np.ndarray | None, int]:
        """(the pose reported this step or None, its age in control steps) for one pose; true = [x, y, z]
        or [x, y, z, rest_z] (the object's)."""
        hist = self.history[name]
        hist.append(true)
        del hist[: max(0, len(hist) - faults.lag_steps - 1)]
        if self.dropped[name] == 0 and faults.dropout > 0.0 and self.rng.random() < faults.dropout / faults.dropout_run:
            self.dropped[name] = faults.dropout_run
        if self.dropped[name] > 0 or len(hist) <= faults.lag_steps:  # missing: hold what was reported last
            self.dropped[name] = max(0, self.dropped[name] - 1)
            if self.held[name] is None:
                return None, faults.lag_steps
            self.age[name] += 1
            return self.held[name], self.age[name]
        bias = self.bias[name]
        seen = hist[0] + np.append(bias, bias[2])[: true.shape[0]]  # rest_z: the z bias, no noise (read at reset)
        seen[:3] += self.rng.normal(0.0, faults.noise_m, 3) if faults.noise_m > 0 else 0.0
        self.held[name], self.age[name] = seen, faults.lag_steps
        return seen, faults.lag_steps


def _direction(rng: np.random.Generator) -> np.ndarray:
    """A unit vector drawn uniformly on the sphere."""
    v = rng.normal(size=3)
    return v / max(float(np.linalg.norm(v)), 1e-12)
