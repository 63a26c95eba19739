"""robosuite Lift scenes (plain and place-on-plate): seeding, the state they read, and scripted episodes."""

import copy

import mujoco
import numpy as np
import pytest

from lerobot_physvla.sim import lift_sim
from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.sim.experts import ExpertConfig, PickPlaceExpert
from lerobot_physvla.sim.lift_sim import LiftScene


@pytest.fixture(scope="module")
def lift():
    return LiftScene()


@pytest.fixture(scope="module")
def lift_plate():
    return LiftScene(plate=True)


def cube_pos(scene) -> np.ndarray:
    """The cube body's position in the current state (forwarded: after a step, xpos lags qpos)."""
    d = copy.copy(scene.env.sim.data._data)
    mujoco.mj_forward(scene.env.sim.model._model, d)
    return d.xpos[scene.env.cube_body_id].copy()


def run(scene, seed: int, corrector=None, **overrides) -> tuple[bool, int]:
    """One harness-style episode of the scripted expert; (success, steps)."""
    scene.reset(seed)
    expert = PickPlaceExpert(cfg=ExpertConfig(**{**scene.expert, **overrides}))
    expert.reset(seed=seed)
    if corrector is not None:
        corrector.reset()
    success = False
    for step in range(1, scene.horizon + 1):
        st = scene.read()
        action = expert.act(st.eef_pos[0], st.obj_pos[0], st.target_pos[0])[None]
        if corrector is not None:
            action = corrector(action, st)
        success, _ = scene.step(action[0])
        if success and scene.stop_on_success:
            break
    return success, step


def test_reset_is_reproducible_per_seed(lift):
    rng = np.random.default_rng(0)
    actions = rng.uniform(-1, 1, (20, 7))

    def rollout(seed):
        lift.reset(seed)
        start = cube_pos(lift)
        traj = []
        for a in actions:
            lift.step(a)
            traj.append(np.concatenate([lift.env.sim.data.qpos, lift.env.sim.data.qvel]))
        return start, np.array(traj)

    start_a, traj_a = rollout(3)
    start_b, _ = rollout(4)
    start_c, traj_c = rollout(3)
    np.testing.assert_array_equal(start_a, start_c)
    np.testing.assert_array_equal(traj_a, traj_c)
    assert np.linalg.norm(start_a[:2] - start_b[:2]) > 1e-3


def test_state_reads_the_cube_and_the_lift_goal(lift):
    lift.reset(5)
    st = lift.read()
    cube = cube_pos(lift)
    assert st.valid[0] and st.episode_step[0] == 0 and st.n_joints == 7
    # the simulator's own position as its last substep left it; within 10 um of the forwarded one (at rest)
    np.testing.assert_array_equal(st.obj_pos[0], lift.env.sim.data._data.xpos[lift.env.cube_body_id])
    np.testing.assert_allclose(st.obj_pos[0], cube, atol=1e-5)
    np.testing.assert_allclose(st.target_pos[0], cube + (0, 0, lift_sim.LIFT_GOAL_M), atol=1e-5)  # at rest
    assert st.obj_rest_z[0] == pytest.approx(cube[2], abs=1e-6)
    assert cube[2] - lift.table_top_z == pytest.approx(0.021, abs=0.002)  # resting: half a cube up
    assert lift.step(lift_sim.NO_OP) == (False, pytest.approx(lift.env.reward()))
    assert lift.read().episode_step[0] == 1


def test_lift_plate_target_is_the_plate_centre(lift_plate):
    lift_plate.reset(5)
    st = lift_plate.read()
    np.testing.assert_allclose(st.target_pos[0], (*lift_sim.PLATE_XY_M, lift_plate.table_top_z), atol=1e-12)
    np.testing.assert_allclose(st.obj_pos[0], cube_pos(lift_plate), atol=1e-5)  # one 2 ms substep older


@pytest.mark.parametrize("seed", [7, 8])
def test_clean_expert_lifts_the_cube(lift, seed):
    success, steps = run(lift, seed)
    assert success and steps == lift.horizon  # scored at the last step: still held up there
    assert cube_pos(lift)[2] - lift.table_top_z > 0.08


@pytest.mark.parametrize("seed", [7, 8])
def test_clean_expert_places_the_cube_on_the_plate(lift_plate, seed):
    success, steps = run(lift_plate, seed)
    assert success and steps < lift_plate.horizon
    assert lift_plate.held == lift_sim.HOLD_STEPS
    assert np.linalg.norm(cube_pos(lift_plate)[:2] - lift_sim.PLATE_XY_M) < lift_sim.PLATE_RADIUS_M


def test_a_large_place_bias_misses_the_plate(lift_plate):
    seed = 8
    draw = PickPlaceExpert(cfg=ExpertConfig(place_bias_units=1.7))
    draw.reset(seed=seed)
    assert np.linalg.norm(draw.place_bias_units) > 1.4  # action units, 7 cm a step
    success, steps = run(lift_plate, seed, place_bias_units=1.7)
    assert not success and steps == lift_plate.horizon
    assert np.linalg.norm(cube_pos(lift_plate)[:2] - lift_sim.PLATE_XY_M) > lift_sim.PLATE_RADIUS_M


def test_phys_el_in_the_loop_never_passes_through(lift_plate):
    corrector = Corrector(PhysVLAConfig.paper(mode="phys_el"))
    success, _ = run(lift_plate, 9, corrector)
    assert success
    assert corrector.steps > 50 and not any(corrector.passthrough_counts.values())
