"""Processor steps: async sub-envs without cross-talk, episode resets, devices, chunks, save/load."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
import torch

from lerobot.envs.utils import preprocess_observation
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.scripts.lerobot_physvla_config import add_corrector
from lerobot_physvla.envs.libero_physvla import LiberoPhysVLAEnvConfig
from lerobot_physvla.processor.physvla_processor import PhysVLACorrectorStep, PhysVLAStateCaptureStep, get_bus
from lerobot_physvla.core.state import PhysState

from conftest import make_state


def post_pipeline(step):
    return PolicyProcessorPipeline(steps=[step], to_transition=policy_action_to_transition,
                                   to_output=transition_to_policy_action)


@pytest.mark.slow
def test_async_sub_envs_each_use_their_own_state_and_reset_memory_per_episode():
    cfg_env = LiberoPhysVLAEnvConfig(task="libero_spatial", task_ids=[0], cameras=False, episode_length=50)
    vec = cfg_env.create_envs(n_envs=2, use_async_envs=True)["libero_spatial"][0]
    env_pre, _ = cfg_env.get_env_processors()
    cfg = PhysVLAConfig.paper(mode="phys", cap=1.0)  # cap 1: the transport EMA shows in the output
    step = PhysVLACorrectorStep(config=cfg.to_dict(), bus="async-test")
    env_pre.steps[0] = PhysVLAStateCaptureStep(bus="async-test")
    post = post_pipeline(step)
    refs = [Corrector(cfg), Corrector(cfg)]  # what each env alone would get
    rng = np.random.default_rng(0)
    try:
        for episode in range(2):
            obs, _ = vec.reset(seed=[episode, episode + 10])
            for refc in refs:
                refc.reset()
            for t in range(4):
                o = env_pre(preprocess_observation(obs))
                assert o["observation.state"].shape == (2, 8) and not any("physvla" in k for k in o)
                rows = get_bus("async-test").state
                assert rows.shape[0] == 2 and not np.allclose(rows[0], rows[1])  # two different scenes
                # make both envs look like they are transporting, so the EMA memory matters
                st = PhysState.unpack(rows.copy())
                st.obj_rest_z[:] = st.obj_pos[:, 2] - 0.05
                st.obj_pos[:, :2] = st.eef_pos[:, :2]
                get_bus("async-test").publish(st.pack())
                raw = rng.uniform(-0.3, 0.3, size=(2, 7)).astype(np.float32)
                out = post(torch.from_numpy(raw)).numpy()
                for i in range(2):
                    alone = refs[i](raw[i : i + 1].astype(np.float64), PhysState.unpack(st.pack()[i]))
                    np.testing.assert_allclose(out[i], alone[0], atol=1e-6)
                assert step.corrector.last.phase.tolist() == [2, 2]  # transport
                obs, *_ = vec.step(out.astype(np.float64))
    finally:
        vec.close()


def test_no_state_passes_through_and_counts():
    step = PhysVLACorrectorStep(bus="empty-bus")
    a = torch.rand(3, 7)
    with pytest.warns(RuntimeWarning, match="libero_physvla"):
        out = post_pipeline(step)(a)
    assert torch.equal(out, a) and step.passthrough_counts == {"no_state": 1}
    assert step.corrector.passthrough_counts == {"no_state": 3}


@pytest.mark.parametrize("mode", ["baseline", "temporal", "phys", "phys_el"])
def test_the_step_never_raises_and_emits_only_finite_in_bounds_actions(mode):
    bus = get_bus(f"garbage-bus-{mode}")
    step = PhysVLACorrectorStep(config=PhysVLAConfig.paper(mode=mode).to_dict(), bus=f"garbage-bus-{mode}")
    pipe = post_pipeline(step)
    bad = torch.tensor([[np.nan, 0.1, 0.1, 0.0, 0.0, 0.0, 1.0], [3.0, -3.0, 0.2, 0.0, 0.0, 0.0, 1.0]])
    out = pipe(bad)  # no state on the bus yet
    assert torch.isfinite(out).all() and (out.abs() <= 1).all()
    st = make_state(batch_size=2)
    st.dt[:] = 0.0
    st.M[1] = np.inf
    bus.publish(st.pack())
    for action in (bad, bad[:, None].repeat(1, 3, 1), torch.full((2, 7), np.inf), torch.zeros(2, 5)):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            out = pipe(action)
        assert out.shape == action.shape and torch.isfinite(out).all() and (out.abs() <= 1).all()
    assert step.passthrough_counts["action_shape_mismatch"] == 1
    bus.publish(np.zeros((2, 5)))  # a packed state of a length no arm has
    with pytest.warns(RuntimeWarning, match="corrector_error"):
        out = pipe(bad)
    assert torch.isfinite(out).all() and (out.abs() <= 1).all()


def test_chunks_dtype_and_batch_mismatch():
    bus = get_bus("chunk-bus")
    st = make_state(batch_size=2, obj=(0.5, 0.0, 0.9))  # approach
    bus.publish(st.pack())
    step = PhysVLACorrectorStep(config=PhysVLAConfig.paper(mode="phys", gripper_rule="veto").to_dict(), bus="chunk-bus")
    chunk = torch.ones(2, 5, 7, dtype=torch.float64) * 0.5
    out = post_pipeline(step)(chunk)
    assert out.shape == chunk.shape and out.dtype == torch.float64
    assert (out[..., 6] == -1).all()  # every step of the chunk is vetoed (chunk="all")
    with pytest.warns(RuntimeWarning, match="state_batch_mismatch"):
        out3 = post_pipeline(step)(torch.zeros(3, 7))
    assert torch.equal(out3, torch.zeros(3, 7))


def test_episode_start_resets_the_memory_of_that_env_only():
    bus = get_bus("episode-bus")
    cfg = PhysVLAConfig.paper(mode="temporal")
    step = PhysVLACorrectorStep(config=cfg.to_dict(), bus="episode-bus")
    st = make_state(batch_size=2)
    post = post_pipeline(step)
    for steps, value in (([0, 0], 1.0), ([1, 1], 1.0)):
        st.episode_step[:] = steps
        bus.publish(st.pack())
        post(torch.full((2, 7), value))
    st.episode_step[:] = [2, 0]  # env 1 was reset (its counter went back)
    bus.publish(st.pack())
    out = post(torch.zeros(2, 7))
    assert out[0, 0] == pytest.approx(0.85)  # env 0 remembers the previous actions
    assert out[1, 0] == 0.0  # env 1 starts afresh


@pytest.mark.slow
def test_save_load_round_trip_in_a_fresh_interpreter(tmp_path):
    cfg = PhysVLAConfig.paper(mode="phys_el", weighting="task_space", gripper_rule="veto", cap=0.07)
    path = add_corrector(tmp_path, cfg)
    entry = json.loads(path.read_text())["steps"][-1]
    assert entry["class"] == "lerobot_physvla.processor.physvla_processor.PhysVLACorrectorStep"
    probe = f"""
import sys
from lerobot.processor import PolicyProcessorPipeline
from lerobot.processor.converters import policy_action_to_transition, transition_to_policy_action
assert not any(m.startswith("lerobot_physvla") for m in sys.modules)
p = PolicyProcessorPipeline.from_pretrained({str(tmp_path)!r}, config_filename="policy_postprocessor.json",
    to_transition=policy_action_to_transition, to_output=transition_to_policy_action)
step = p.steps[-1]
print(type(step).__module__, step.cfg.mode, step.cfg.weighting, step.cfg.gripper_rule, step.cfg.cap)
"""
    r = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=300, cwd=tmp_path)
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split() == ["lerobot_physvla.processor.physvla_processor", "phys_el", "task_space", "veto", "0.07"]


def test_add_corrector_replaces_an_existing_one(tmp_path):
    add_corrector(tmp_path, PhysVLAConfig.paper(mode="phys"))
    add_corrector(tmp_path, PhysVLAConfig.paper(mode="temporal"))
    steps = json.loads((tmp_path / "policy_postprocessor.json").read_text())["steps"]
    assert [s["config"]["config"]["mode"] for s in steps] == ["temporal"]


def test_unknown_mode_in_a_config_is_a_clear_error():
    with pytest.raises(ValueError, match="unknown mode 'turbo'"):
        PhysVLACorrectorStep(config={"mode": "turbo"})


@pytest.mark.parametrize("save_states", [False, True])
def test_the_recorder_row_written_inside_the_tick_is_the_row_a_listener_copies(save_states):
    """lerobot-eval's recorder, the step's only listener, has its row written by the compiled tick
    (EpisodeRecorder.slot / commit); any other listener set copies it in Python after the call. Both
    must record the same episodes: float32 and float64 actions (one compiled call each), chunks
    (the corrector's path in steps), extras, batches that restart, more steps than the first capacity."""
    from lerobot_physvla.core.config import LAYOUTS, PRESETS
    from lerobot_physvla.diagnostics import EpisodeRecorder, _Segment

    lay = LAYOUTS["libero_osc_pose"]
    cfg = PRESETS["default"].to_dict()
    folded, copied = (PhysVLACorrectorStep(config=cfg, bus=f"fold-{save_states}-{i}") for i in range(2))
    recs = [EpisodeRecorder(layout=lay, keep_steps=None, save_states=save_states) for _ in range(2)]
    folded.listeners.append(recs[0])
    copied.listeners += [recs[1], lambda *args: None]  # two listeners: the copying path
    rng = np.random.default_rng(5)
    for batch, steps in enumerate((40, _Segment.CAPACITY + 30, 25)):
        for t in range(steps):
            st = make_state(batch_size=2, obj=(0.02 * (30 - t % 30), 0.0, 0.9), seed=t)
            st.episode_step[:] = t
            extra = np.zeros((2, 9))
            extra[:, 0], extra[:, 2:] = batch, rng.uniform(-1, 1, (2, 7))
            a = rng.uniform(-1.2, 1.2, (2, 5, 7) if t % 11 == 5 else (2, 7))
            act = torch.from_numpy(a.astype(np.float32) if t % 4 else a)
            outs = []
            for step in (folded, copied):
                get_bus(step.bus).publish(st.pack(), torch.from_numpy(extra))
                outs.append(post_pipeline(step)(act.clone()))
            assert torch.equal(outs[0], outs[1])
    a, b = recs[0].records(), recs[1].records()
    assert len(a) == 6 and [r["steps"] for r in a] == [40, 40, _Segment.CAPACITY + 30, _Segment.CAPACITY + 30, 25, 25]
    for ra, rb in zip(a, b):
        for key, value in rb.items():
            if key not in ("overhead_us_p50", "overhead_us_p99"):  # the call times differ
                assert ra[key] == value or (value != value and ra[key] != ra[key]), key
    for ea, eb in zip(recs[0].episodes, recs[1].episodes):
        np.testing.assert_array_equal(ea.raw, eb.raw)
        np.testing.assert_array_equal(ea.states, eb.states)
        assert ea.states.shape[1] == (st.pack().shape[1] if save_states else 0)
