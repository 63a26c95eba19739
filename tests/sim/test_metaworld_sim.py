"""MetaWorld as a harness scene (metaworld/<k>, state-only) and MetaWorld's own scripted policies as the teacher:
seeded resets, the state against the simulator, lerobot-eval's start and observation, the clean teacher, and each
failure mode changing the teacher's actions but never the scene."""

from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

pytest.importorskip("metaworld")

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))
from backbones import ExpertBackbone  # noqa: E402

from lerobot_physvla.core.config import LAYOUTS, preset  # noqa: E402
from lerobot_physvla.core.corrector import Corrector  # noqa: E402
from lerobot_physvla.core.state import PhysState  # noqa: E402
from lerobot_physvla.sim.metaworld_expert import POLICIES, MetaworldExpert, MetaworldExpertConfig  # noqa: E402
from lerobot_physvla.sim.metaworld_sim import ALL_TASKS, HORIZON, PASS_THROUGH, TASKS, task_name  # noqa: E402
from lerobot_physvla.sim.scenes import make_scene  # noqa: E402
from lerobot_physvla.sources.metaworld import MODELLED  # noqa: E402


@pytest.fixture(scope="module")
def scene():
    sc = make_scene("metaworld/0")
    yield sc
    sc.env.close()


def test_the_scenes_are_the_modelled_tasks_in_a_fixed_order_with_their_own_policies():
    from lerobot.envs.metaworld import TASK_POLICY_MAPPING

    assert TASKS == ("pick-place-v3", "pick-place-wall-v3", "bin-picking-v3", "shelf-place-v3", "basketball-v3",
                     "pick-out-of-hole-v3")
    assert set(TASKS) == set(MODELLED) and set(POLICIES) == set(TASKS)
    assert all(TASK_POLICY_MAPPING[t].__name__ == POLICIES[t] for t in TASKS)  # lerobot's mapping: the same


def test_an_unknown_scene_or_task_index_is_a_clear_error():
    for bad in ("metaworld/50", "metaworld/-1"):
        with pytest.raises(ValueError, match=r"metaworld/<k>"):
            make_scene(bad)
    with pytest.raises(ValueError, match=r"no MetaWorld scene index 50; .*0 pick-place-v3, .*5 pick-out-of-hole-v3"):
        make_scene("metaworld/50")
    with pytest.raises(ValueError, match="named metaworld/<k>"):
        make_scene("metaworld")
    with pytest.raises(ValueError, match="no MetaWorld scene index"):
        task_name(len(ALL_TASKS))


def test_the_scene_is_metaworlds_own_episode(scene):
    assert scene.name == "metaworld/0" and scene.task.name == "pick-place-v3" and scene.task.index == 0
    assert scene.horizon == HORIZON == scene.env.max_path_length == 500 and scene.stop_on_success
    assert scene.layout == LAYOUTS["metaworld"] and scene.teacher == "metaworld"
    assert scene.task.language  # lerobot's instruction for the task


def test_seeded_resets_are_reproducible_and_differ_across_seeds(scene):
    actions = np.random.default_rng(0).uniform(-1, 1, (10, 4))

    def rollout(seed):
        scene.reset(seed)
        start, obs0 = scene.read().pack(), scene.raw_obs.copy()
        for a in actions:
            scene.step(a)
        return start, obs0, scene.read().pack()

    (s1, o1, end1), (s2, o2, end2), (s3, _, _) = rollout(5), rollout(5), rollout(6)
    np.testing.assert_array_equal(s1, s2)
    np.testing.assert_array_equal(o1, o2)
    np.testing.assert_array_equal(end1, end2)
    a, c = PhysState.unpack(s1), PhysState.unpack(s3)
    assert not np.allclose(a.obj_pos, c.obj_pos) and not np.allclose(a.target_pos, c.target_pos)


def test_the_state_is_the_simulators(scene):
    scene.reset(1)
    env = scene.env
    for k in range(5):
        st = scene.read()
        assert st.valid[0] and st.episode_step[0] == k and st.dt[0] == pytest.approx(0.0125)
        np.testing.assert_allclose(st.eef_pos[0], env.tcp_center, atol=1e-12)
        np.testing.assert_allclose(st.obj_pos[0], scene.raw_obs[4:7], atol=1e-9)  # the observation's object
        np.testing.assert_array_equal(st.target_pos[0], env._target_pos)
        np.testing.assert_array_equal(st.target_pos[0], scene.raw_obs[36:39])  # the goal the policies read
        obs = scene.policy_observation(st)
        assert obs["observation.state"].dtype == np.float32 and obs["observation.state"].shape == (4,)
        np.testing.assert_array_equal(obs["observation.state"], scene.raw_obs[:4].astype(np.float32))
        np.testing.assert_array_equal(obs["observation.environment_state"],
                                      np.concatenate([st.obj_pos[0], st.target_pos[0]]).astype(np.float32))
        scene.step(np.array([0.3, -0.2, 0.1, 1.0]))


def test_a_seed_starts_where_lerobot_eval_starts_it_and_the_policy_sees_what_it_sees(scene):
    """`--env.type=metaworld_physvla --env.cameras=false --env.obs_type=pixels_agent_pos` with seed s: the same
    object, goal and hand as the scene's reset(s), and the same state observation."""
    from lerobot_physvla.envs.metaworld_physvla import _make_env

    env = _make_env("pick-place-v3", 0, {"obs_type": "pixels_agent_pos"}, False, None, None)
    try:
        for seed in (0, 3):
            obs, _ = env.reset(seed=seed)
            scene.reset(seed)
            mine = scene.policy_observation(scene.read())
            np.testing.assert_allclose(mine["observation.state"], obs["agent_pos"], atol=1e-6)
            np.testing.assert_allclose(mine["observation.environment_state"], obs["environment_state"], atol=1e-6)
    finally:
        env.close()


def _episode(scene, backbone, seed):
    scene.reset(seed)
    backbone.reset(seed)
    for steps in range(1, scene.horizon + 1):
        success, _ = scene.step(backbone.act(scene, scene.read()))
        if success:
            return True, steps
    return False, steps


def test_the_clean_teacher_succeeds_on_pick_place(scene):
    backbone = ExpertBackbone(scene, {})  # the scene's own teacher
    assert backbone.teacher == "metaworld" and isinstance(backbone.expert, MetaworldExpert)
    success, steps = _episode(scene, backbone, 0)
    assert success and steps < 100  # measured: 53 steps


FAILURES = {
    "action_noise": {"action_noise": 0.5},
    "aim_noise_m": {"aim_noise_m": 0.02},
    "place_bias_m": {"place_bias_m": 0.08},
    "premature_close": {"premature_close": 1.0},
    "no_decel": {"no_decel": True},
}


def test_each_failure_mode_changes_the_teachers_actions_and_never_the_scene(scene):
    """The clean teacher drives the episode; beside it, one faulty teacher per mode acts on the same observation
    each step. Each changes its actions where its mode says, and acting leaves the scene's state and observation
    as they were."""
    clean = MetaworldExpert("pick-place-v3")
    faulty = {m: MetaworldExpert("pick-place-v3", MetaworldExpertConfig(**f)) for m, f in FAILURES.items()}
    scene.reset(0)
    clean.reset(0)
    for t in faulty.values():
        t.reset(0)
    diffs = {m: [] for m in FAILURES}
    carrying = []
    for _ in range(60):
        st, obs = scene.read().pack(), scene.raw_obs.copy()
        a = clean.act(scene.raw_obs)
        for m, t in faulty.items():
            diffs[m].append(t.act(scene.raw_obs) - a)
            np.testing.assert_array_equal(scene.read().pack(), st)  # the state the corrector reads: unchanged
            np.testing.assert_array_equal(scene.raw_obs, obs)  # the scene's observation: unchanged
        carrying.append(clean.carrying)
        scene.step(a)
    d = {m: np.array(v) for m, v in diffs.items()}
    carrying = np.array(carrying)
    assert carrying.any() and not carrying[0]  # the episode reaches the carry
    # action noise: the x, y channels (every step but where a saturated command clips it away), nothing else
    assert (np.abs(d["action_noise"][:, :2]) > 0).any(axis=1).mean() > 0.8 and not d["action_noise"][:, 2:].any()
    # aim error: the approach already aims elsewhere: it sees the object (of the last step, obs) moved by its offset
    aim = faulty["aim_noise_m"]
    assert aim.aim[:2].all() and d["aim_noise_m"][~carrying][:, :3].any()
    np.testing.assert_allclose(aim.seen[4:6] - obs[4:6], aim.aim[:2], atol=1e-12)
    # place bias: nothing before the carry, a different carry after it, the hand and the object seen shifted
    bias = faulty["place_bias_m"]
    assert bias.place_bias[:2].all() and bias.carrying
    assert not d["place_bias_m"][~carrying].any() and d["place_bias_m"][carrying][:, :3].any()
    for at in (0, 4):
        np.testing.assert_allclose(bias.seen[at : at + 2] - obs[at : at + 2], -bias.place_bias[:2],
                                   atol=1e-12)
    # premature close: the gripper commanded shut while the policy still opens (the hand starts 8 cm from the puck)
    early = faulty["premature_close"]
    assert early.close_early and d["premature_close"][0, 3] > 0 and not d["premature_close"][:, :3].any()
    # no deceleration: the same until the carry, then full-speed moves
    nd = d["no_decel"]
    assert not nd[~carrying].any() and np.abs(nd[carrying]).max() > 0.05


def test_failure_draws_are_per_episode_seed_and_reproducible():
    t = MetaworldExpert("bin-picking-v3", MetaworldExpertConfig(aim_noise_m=0.02, place_bias_m=0.08,
                                                                premature_close=0.5))

    def draws(seed):
        t.reset(seed)
        return (*t.aim, *t.place_bias, t.close_early)

    assert draws(3) == draws(3) and draws(3) != draws(4)
    assert len({draws(s)[-1] for s in range(20)}) == 2  # the early close fires in some episodes, not all


def test_unsupported_fields_and_scenes_are_clear_errors(scene):
    with pytest.raises(ValueError, match="does not support 'hover_m'"):
        ExpertBackbone(scene, {"teacher": "metaworld", "hover_m": 0.1})
    with pytest.raises(ValueError, match="does not support 'place_bias_units'"):
        ExpertBackbone(scene, {"place_bias_units": 1.7})
    with pytest.raises(ValueError, match="unknown field 'bogus'"):
        ExpertBackbone(scene, {"bogus": 1})
    with pytest.raises(ValueError, match="noise_stage"):
        ExpertBackbone(scene, {"noise_stage": "place"})
    with pytest.raises(ValueError, match="metaworld/<k> scenes only"):
        ExpertBackbone(SimpleNamespace(name="lift", layout=LAYOUTS["metaworld"], expert={}), {"teacher": "metaworld"})
    with pytest.raises(ValueError, match="no metaworld teacher for 'no-such-task-v3'"):
        MetaworldExpert("no-such-task-v3")
    assert ExpertBackbone(scene, {"teacher": "metaworld", "draw_offset": 7}).draw_offset == 7


def test_the_task_descriptions_are_lerobots():
    from lerobot.envs.metaworld import TASK_DESCRIPTIONS

    from lerobot_physvla.sim import metaworld_sim

    assert set(metaworld_sim.DESCRIPTIONS) == set(metaworld_sim.TASKS)
    for task, words in metaworld_sim.DESCRIPTIONS.items():
        assert TASK_DESCRIPTIONS[task] == words


def test_the_other_44_tasks_are_pass_through_scenes_with_metaworlds_own_policies():
    from metaworld.env_dict import ALL_V3_ENVIRONMENTS

    from lerobot_physvla.sources.metaworld import UNSUPPORTED

    assert set(ALL_TASKS) == set(ALL_V3_ENVIRONMENTS) and len(ALL_TASKS) == 50
    assert ALL_TASKS[:6] == TASKS and PASS_THROUGH == tuple(sorted(UNSUPPORTED))
    sc = make_scene(f"metaworld/{ALL_TASKS.index('door-open-v3')}")
    assert not sc.task.modelled and sc.source is None
    sc.reset(3)
    st = sc.read()
    assert st.valid[0] == -1.0 and st.dt[0] == sc.env.dt and np.allclose(st.eef_pos[0], sc.env.tcp_center)
    bb = ExpertBackbone(sc, {})  # the scene's teacher: MetaWorld's door-open policy
    c = Corrector(preset("default", layout="metaworld", weighting="task_space"))
    for _ in range(20):
        st = sc.read()
        raw = np.asarray(bb.act(sc, st), dtype=np.float64)[None]
        out = c(raw, st)
        assert np.array_equal(out, raw)  # passed through, bit for bit
        sc.step(out[0])
    assert c.passthrough_counts == {"unsupported_goal": 20}
    assert sc.read().episode_step[0] == 20
