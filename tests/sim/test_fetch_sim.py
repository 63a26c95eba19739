"""FetchPickAndPlace-v4 as a scene: its state against the env's own observation, seeding, the clean
expert, and phys_el in the loop."""

import numpy as np
import pytest

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert
from lerobot_physvla.sim.fetch_sim import FetchScene, FetchStateSource


@pytest.fixture(scope="module")
def scene():
    sc = FetchScene()
    yield sc
    sc.env.close()


def _episode(scene, corrector, seed):
    """One clean-expert episode through `corrector`; returns (success at the last step, actions sent)."""
    expert = PickPlaceExpert(layout=scene.layout, cfg=ExpertConfig(**scene.expert))
    scene.reset(seed)
    corrector.reset()
    sent = []
    for _ in range(scene.horizon):
        st = scene.read()
        out = corrector(expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])[None], st)
        sent.append(out[0])
        success, _ = scene.step(out[0])
    return success, np.array(sent)


def test_state_matches_the_observation(scene):
    scene.reset(3)
    for k in range(4):
        st, obs = scene.read(), scene.raw_obs["observation"]
        assert st.valid[0] and st.episode_step[0] == k and st.dt[0] == pytest.approx(0.04)
        np.testing.assert_array_equal(st.eef_pos[0], obs[:3])
        np.testing.assert_array_equal(st.obj_pos[0], obs[3:6])
        np.testing.assert_array_equal(st.target_pos[0], scene.raw_obs["desired_goal"])
        assert st.gripper[0] == pytest.approx(np.abs(obs[9:11]).sum())
        scene.step(np.array([0.5, -0.5, 0.5, 1.0]))
    assert st.obj_rest_z[0] == pytest.approx(scene.env.unwrapped.height_offset, abs=1e-3)
    assert st.n_joints == 7 and np.linalg.matrix_rank(st.J_pos[0]) == 3
    M = st.M[0]
    np.testing.assert_allclose(M, M.T, atol=1e-12)
    assert np.linalg.eigvalsh(M).min() > 0
    assert np.linalg.norm(st.qdot[0]) > 0  # the arm moves: the weld drags the joints along


def test_reset_is_reproducible_per_seed(scene):
    actions = np.random.default_rng(0).uniform(-1, 1, (10, 4))

    def rollout(seed):
        scene.reset(seed)
        start = scene.read()
        for a in actions:
            scene.step(a)
        return start, scene.read().pack()

    (s1, end1), (s2, end2), (s3, _) = rollout(5), rollout(5), rollout(6)
    np.testing.assert_array_equal(s1.pack(), s2.pack())
    np.testing.assert_array_equal(end1, end2)
    assert not np.allclose(s1.target_pos, s3.target_pos) and not np.allclose(s1.obj_pos, s3.obj_pos)


def test_clean_expert_succeeds(scene):
    wins = [_episode(scene, Corrector(PhysVLAConfig.paper(mode="baseline", layout="fetch_4d")), s)[0] for s in range(10)]
    assert sum(wins) >= 9, wins  # measured: 50 of seeds 0..49


def test_phys_el_in_the_loop(scene):
    # joint_diag would weight 7 joints onto 4 action entries (the corrector refuses): task space
    corr = Corrector(PhysVLAConfig.paper(mode="phys_el", layout="fetch_4d", weighting="task_space"))
    for seed in range(3):
        success, sent = _episode(scene, corr, seed)
        assert success and np.isfinite(sent).all() and (np.abs(sent) <= 1.0).all()
        assert np.isfinite(corr.last.r_el[0]) and corr.last.weights[0].sum() > 0
    assert not corr.passthrough_counts


def test_missing_names_list_what_exists(scene):
    with pytest.raises(ValueError, match="object0") as e:
        FetchStateSource(scene.env, obj_site="object7")
    assert "object7" in str(e.value)
    with pytest.raises(ValueError, match="robot0:grip"):
        FetchStateSource(scene.env, eef_site="robot0:palm")
    with pytest.raises(ValueError, match="robot0:wrist_roll_joint"):
        FetchStateSource(scene.env, finger_joints=("robot0:thumb_joint",))


def test_a_failed_read_is_an_invalid_row(scene, monkeypatch):
    src = FetchStateSource(scene.env)
    scene.reset(0)
    src.reset()
    monkeypatch.setattr(src.oracle, "read", lambda data: 1 / 0)
    with pytest.warns(RuntimeWarning, match="ZeroDivisionError"):
        st = src.read()
    assert st.valid[0] == 0 and src.failures == {"ZeroDivisionError": 1}
