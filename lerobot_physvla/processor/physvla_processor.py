"""LeRobot processor steps: capture the physical state (pre), correct the action (post).

`lerobot-eval` hands the policy postprocessor the action alone, so the physical state travels
another way: the env (see `lerobot_envs.py`) exports a packed state vector in its observation
(`robot_state["physvla_state"]`, (B, L) once vectorised, also from async worker processes);
`PhysVLAStateCaptureStep`, first in the env preprocessor, pops it and publishes it on a named
in-process `StateBus`; `PhysVLACorrectorStep`, last in the policy postprocessor, reads the bus and
corrects the action. Episode boundaries are detected from the state's own `episode_step`
counter (0 right after a reset), per env, because lerobot-eval never calls `reset()`.
"""

from __future__ import annotations

import time
import warnings
from collections import Counter
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from lerobot.configs import PipelineFeatureType, PolicyFeature
from lerobot.lerobot_types import EnvTransition, TransitionKey
from lerobot.processor.pipeline import ProcessorStep, ProcessorStepRegistry
from lerobot.utils.constants import OBS_PREFIX

from lerobot_physvla.core.config import DEFAULT_PRESET, PRESETS, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.diagnostics import EpisodeRecorder

STATE_KEY = "physvla_state"  # inside robot_state: the packed PhysState row (L,)
EXTRA_KEY = "physvla_extra"  # inside robot_state: [task_id, is_success, last executed action (A)]
ROBOT_STATE = f"{OBS_PREFIX}robot_state"
FLAT_STATE = f"{OBS_PREFIX}{STATE_KEY}"  # top-level alternative (datasets, robots)


class StateBus:
    """Latest physical state of B envs, handed from the capture step to the corrector step.

    Attributes:
        state: (B, L) packed states, or None before the first observation.
        extra: (B, E) extras exported by the env (task id, success, executed action) or None;
            converted from the observation's tensor only when read (the recorder reads it).
        seq: incremented at every publish.
    """

    def __init__(self) -> None:
        self.state: np.ndarray | None = None
        self.seq = 0
        self._extra = self._extra_raw = None

    def publish(self, state: np.ndarray, extra=None) -> None:
        self.state, self._extra_raw, self._extra = state, extra, None
        self.seq += 1

    @property
    def extra(self) -> np.ndarray | None:
        if self._extra is None and self._extra_raw is not None:
            self._extra = np.atleast_2d(_to_numpy(self._extra_raw))
        return self._extra


_BUSES: dict[str, StateBus] = {}


def get_bus(name: str = "default") -> StateBus:
    """The process-wide bus of that name (capture and corrector steps meet on it)."""
    return _BUSES.setdefault(name, StateBus())


def _to_numpy(x) -> np.ndarray:
    """A float array of x, with no copy where it can be had (a CPU tensor's own memory)."""
    if isinstance(x, torch.Tensor):
        try:
            a = x.numpy()  # the fast path: a CPU tensor that needs no grad
        except (RuntimeError, TypeError):  # requires grad, not on the CPU, or a dtype numpy lacks (bf16)
            a = x.detach().cpu().double().numpy()
    else:
        a = np.asarray(x)
    return a if a.dtype.kind == "f" else a.astype(np.float64)


def _like(out: np.ndarray, action: torch.Tensor) -> torch.Tensor:
    """out (float32 or float64) as a new tensor of the action's dtype and device (numpy's cast costs less than torch's)."""
    if action.dtype is torch.float32:
        t = torch.from_numpy(out if out.dtype == np.float32 else out.astype(np.float32))
    else:
        t = torch.from_numpy(out).to(dtype=action.dtype)
    return t if action.is_cpu else t.to(action.device)


def _safe_any_shape(a: np.ndarray, low: float, high: float) -> np.ndarray:
    """Last resort for actions the layout does not fit: non-finite -> 0, clipped to [low, high]."""
    return np.clip(np.where(np.isfinite(a), a, 0.0), low, high)


def _unregister_name_for_saving(cls):
    """Keep the step in ProcessorStepRegistry (configs naming it load once the plugin is imported)
    but make `save_pretrained` write its `"class"` path, so a saved pipeline loads in an
    interpreter that never imported lerobot_physvla (the module is imported by that path)."""
    del cls._registry_name
    return cls


@_unregister_name_for_saving
@ProcessorStepRegistry.register("physvla_state_capture")
@dataclass
class PhysVLAStateCaptureStep(ProcessorStep):
    """Takes the env-exported physical state out of the observation and publishes it.

    Put it first in the env preprocessor (the `libero_physvla` env type does). It removes
    `observation.robot_state["physvla_state"]` (and `physvla_extra`), or a top-level
    `observation.physvla_state`, so the policy never sees them.

    Attributes:
        bus: name of the StateBus to publish on.
    """

    bus: str = "default"
    _bus: StateBus | None = field(default=None, init=False, repr=False)

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        obs = transition.get(TransitionKey.OBSERVATION)
        if not obs:
            return transition
        rs = obs.get(ROBOT_STATE)
        extra = None
        if isinstance(rs, dict) and STATE_KEY in rs:
            rs = dict(rs)
            state = rs.pop(STATE_KEY)
            extra = rs.pop(EXTRA_KEY, None)
            obs = dict(obs)
            if rs:
                obs[ROBOT_STATE] = rs
            else:
                del obs[ROBOT_STATE]
        elif FLAT_STATE in obs:
            obs = dict(obs)
            state = obs.pop(FLAT_STATE)
        else:
            return transition
        state = _to_numpy(state)
        bus = self._bus if self._bus is not None else self._bind_bus()
        bus.publish(state[None] if state.ndim == 1 else state, extra)
        new = dict(transition)
        new[TransitionKey.OBSERVATION] = obs
        return new

    def _bind_bus(self) -> StateBus:
        self._bus = get_bus(self.bus)
        return self._bus

    def get_config(self) -> dict[str, Any]:
        return {"bus": self.bus}

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        out = {k: dict(v) for k, v in features.items()}
        for feats in out.values():
            feats.pop(FLAT_STATE, None)
        return out


@_unregister_name_for_saving
@ProcessorStepRegistry.register("physvla_corrector")
@dataclass
class PhysVLACorrectorStep(ProcessorStep):
    """Corrects the action tensor with the PhysVLA corrector, using the state on the bus.

    Put it last in the policy postprocessor (after unnormalisation: it works in env units).
    Accepts (B, A) and (B, T, A) actions on any device and returns the same shape, dtype and
    device. Do-no-harm: it never raises; with no state on the bus, a state whose batch does not
    match, or any error, the action passes through inside the safety net (clipped to the bounds,
    a non-finite action replaced by the hold action; see core/corrector.py) and the reason is
    counted in `passthrough_counts` and warned once.

    Attributes:
        config: PhysVLAConfig fields (mode and every hyperparameter), JSON-serialisable; by
            default the `default` preset (core.config.PRESETS).
        bus: name of the StateBus to read.
    """

    config: dict[str, Any] = field(default_factory=lambda: PRESETS[DEFAULT_PRESET].to_dict())
    bus: str = "default"
    passthrough_counts: Counter = field(default_factory=Counter, init=False, repr=False)
    listeners: list = field(default_factory=list, init=False, repr=False)
    _corrector: Corrector | None = field(default=None, init=False, repr=False)
    _bus: StateBus | None = field(default=None, init=False, repr=False)

    def __post_init__(self) -> None:
        self.cfg = PhysVLAConfig.from_dict(self.config)  # validates: unknown mode -> ValueError
        self.config = self.cfg.to_dict()
        self._layout = self.cfg.action_layout
        # Built (and its kernels compiled / loaded) with the step, never inside the first control tick.
        self._corrector = Corrector(self.cfg, 1)
        torch.from_numpy(_to_numpy(torch.zeros(1, self.cfg.action_layout.dim))).to(dtype=torch.float32)

    @property
    def corrector(self) -> Corrector | None:
        return self._corrector

    def _warn(self, why: str, fix: str) -> None:
        self.passthrough_counts[why] += 1
        if self.passthrough_counts[why] == 1:
            warnings.warn(f"physvla: passing actions through ({why}): {fix}", RuntimeWarning, stacklevel=4)

    def _bind_bus(self) -> StateBus:
        self._bus = get_bus(self.bus)
        return self._bus

    def _ensure_corrector(self, b: int) -> Corrector:
        if self._corrector is None or self._corrector.batch_size != b:
            self._corrector = Corrector(self.cfg, b)
        return self._corrector

    def __call__(self, transition: EnvTransition) -> EnvTransition:
        action = transition.get(TransitionKey.ACTION)
        if not isinstance(action, torch.Tensor):
            return transition
        try:
            out = self._correct(action)
        except Exception as e:  # noqa: BLE001 - do-no-harm: the corrector never stops a rollout
            self._warn("corrector_error", f"{type(e).__name__}: {e}")
            lay = self._layout
            out = _safe_any_shape(_to_numpy(action), lay.low, lay.high)
        new = dict(transition)
        new[TransitionKey.ACTION] = _like(out, action)
        return new

    def _correct(self, action: torch.Tensor) -> np.ndarray:
        """Corrected actions (numpy: float32 for a float32 action on the one-call path, else float64);
        every path ends inside the action bounds, finite."""
        raw = _to_numpy(action)
        lay = self._layout
        if raw.ndim not in (2, 3) or raw.shape[-1] != lay.dim:
            self._warn("action_shape_mismatch", f"actions of shape {tuple(raw.shape)} for the layout's dim "
                       f"{lay.dim}; set --physvla.layout to the env's action layout")
            return _safe_any_shape(raw, lay.low, lay.high)
        b = raw.shape[0]
        corrector = self._corrector
        if corrector is None or corrector.batch_size != b:
            corrector = self._ensure_corrector(b)
        bus = self._bus if self._bus is not None else self._bind_bus()
        if bus.state is None:
            self._warn("no_state", "no physical state reached the postprocessor; evaluate with "
                       "--env.type=libero_physvla (or --policy.postprocess=physvla), or feed observation.physvla_state")
            return corrector.passthrough(raw, "no_state")
        flat = bus.state
        if flat.shape[0] != b:
            self._warn("state_batch_mismatch", f"state for {flat.shape[0]} envs, action for {b}")
            return corrector.passthrough(raw, "state_batch_mismatch")
        # Episode boundaries (an env whose step counter went back starts afresh) and the correction:
        # one compiled call (Corrector.correct_stream)
        listeners = self.listeners
        if not listeners:
            return corrector.correct_stream(raw, flat)
        if len(listeners) == 1 and type(listeners[0]) is EpisodeRecorder:
            # lerobot-eval's recorder: the compiled tick writes the step's row into its arena (one
            # call; no array copies in Python after it)
            rec, extra = listeners[0], bus.extra
            rows, k = rec.slot(b, lay.dim, corrector.diag_buffer.shape[1], extra, flat)
            t0 = time.perf_counter()
            out = corrector.correct_stream(raw, flat, rows, k)
            rec.commit(extra, (time.perf_counter() - t0) * 1e6 / b)
            return out
        t0 = time.perf_counter()
        out = corrector.correct_stream(raw, flat)
        t_total = time.perf_counter() - t0
        for listener in self.listeners:  # per-step recording only when someone listens
            listener(raw, out, flat, bus.extra, corrector, t_total)
        return out

    def get_config(self) -> dict[str, Any]:
        return {"config": self.config, "bus": self.bus}

    def reset(self) -> None:
        """Forget all per-env memory (the next call starts every env's episode afresh)."""
        if self._corrector is not None:
            self._corrector.reset()

    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        return features

