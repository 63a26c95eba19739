"""The corrector: modes, blender, batching, chunks, per-env memory and the do-no-harm contract."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st_

from lerobot_physvla.core.config import MODES, PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.phase import Phase

from conftest import make_state

RAW = np.array([[0.4, -0.2, 0.1, 0.3, 0.0, -0.3, 1.0]])


def test_baseline_is_identity():
    c = Corrector(PhysVLAConfig.paper(mode="baseline"))
    out = c(RAW, make_state())
    np.testing.assert_array_equal(out, RAW)


def test_phys_blends_branch_a_with_the_cap():
    st = make_state(eef=(0, 0, 1.0), obj=(0.01, -0.02, 0.95))  # grasp phase
    out = Corrector(PhysVLAConfig.paper(mode="phys"))(RAW, st)
    a_phys = RAW.copy()
    a_phys[0, :3] = 0.5 * np.array([0.2, -0.4, -1.0]) + 0.5 * RAW[0, :3]
    np.testing.assert_allclose(out, 0.95 * RAW + 0.05 * a_phys)


def test_gripper_rules_in_approach():
    st = make_state(obj=(0.5, 0.0, 0.9))  # approach
    blend = Corrector(PhysVLAConfig.paper(mode="phys", gripper_rule="blend"))(RAW, st)
    veto = Corrector(PhysVLAConfig.paper(mode="phys", gripper_rule="veto"))(RAW, st)
    assert blend[0, 6] == pytest.approx(0.9) and veto[0, 6] == -1.0
    np.testing.assert_allclose(blend[0, :6], veto[0, :6])
    st_grasp = make_state()  # grasp: no veto
    assert Corrector(PhysVLAConfig.paper(mode="phys", gripper_rule="veto"))(RAW, st_grasp)[0, 6] == 1.0


def test_temporal_mode_is_a_uniform_position_ema():
    c = Corrector(PhysVLAConfig.paper(mode="temporal"))
    st = make_state()
    out1 = c(RAW, st)
    np.testing.assert_allclose(out1, RAW)
    raw2 = np.zeros((1, 7))
    out2 = c(raw2, st)
    np.testing.assert_allclose(out2[0, :3], 0.85 * RAW[0, :3])
    np.testing.assert_array_equal(out2[0, 3:], 0.0)
    c.reset()
    np.testing.assert_allclose(c(raw2, st), raw2)


def test_batched_envs_do_not_interact():
    st = make_state(batch_size=3, seed=1)
    st.obj_pos[0] = (0.5, 0, 0.9)  # approach
    st.obj_pos[1] = (0.0, 0, 0.95)
    st.obj_rest_z[1] = 0.9  # lifted -> transport
    raw = np.repeat(RAW, 3, axis=0)
    together = Corrector(PhysVLAConfig.paper(), 3)(raw, st)
    for i in range(3):
        alone = Corrector(PhysVLAConfig.paper(), 1)(raw[i : i + 1], _row(st, i))
        np.testing.assert_allclose(together[i], alone[0], atol=1e-12)


def _row(st, i):
    from lerobot_physvla.core.state import PhysState

    return PhysState.unpack(st.pack()[i : i + 1])


def test_per_env_reset_of_transport_memory():
    st = make_state(batch_size=2, obj=(0, 0, 0.95), lift=0.05)  # both transporting
    c = Corrector(PhysVLAConfig.paper(mode="phys"), 2)
    raw = np.repeat(RAW, 2, axis=0)
    c(raw, st)
    c.reset([1])
    out = c(np.zeros((2, 7)), st)
    assert Phase(c.last.phase[0]) == Phase.TRANSPORT
    assert abs(out[0, 0]) > 0  # env 0 still remembers the first action
    # env 1 restarted: its EMA equals its new input, 0 plus the lift bias (0.4 units on z), capped at 5 %
    np.testing.assert_allclose(out[1, :3], [0.0, 0.0, 0.05 * 0.4])


def test_chunks_all_and_first():
    st = make_state(obj=(0.5, 0, 0.9))  # approach: veto changes the gripper of every corrected step
    chunk = np.repeat(RAW[:, None, :], 4, axis=1)  # (B=1, T=4, A=7)
    all_ = Corrector(PhysVLAConfig.paper(mode="phys", gripper_rule="veto", chunk="all"))(chunk, st)
    first = Corrector(PhysVLAConfig.paper(mode="phys", gripper_rule="veto", chunk="first"))(chunk, st)
    assert all_.shape == chunk.shape
    assert (all_[0, :, 6] == -1.0).all()
    assert first[0, 0, 6] == -1.0 and (first[0, 1:, 6] == 1.0).all()


def test_chunk_steps_do_not_advance_memory():
    st = make_state(obj=(0, 0, 0.95), lift=0.05)  # transport
    chunk = np.stack([RAW[0], np.zeros(7), np.zeros(7)])[None]
    c = Corrector(PhysVLAConfig.paper(mode="phys"))
    c(chunk, st)
    after_chunk = c(np.zeros((1, 7)), st)
    c2 = Corrector(PhysVLAConfig.paper(mode="phys"))
    c2(RAW, st)
    np.testing.assert_allclose(after_chunk, c2(np.zeros((1, 7)), st))  # same memory as one step of RAW


def test_shape_errors_are_raised_at_the_boundary():
    c = Corrector(PhysVLAConfig.paper(), 2)
    with pytest.raises(ValueError, match="batch_size=2"):
        c(np.zeros((1, 7)), make_state(batch_size=1))
    with pytest.raises(ValueError, match="layout"):
        c(np.zeros((2, 4)), make_state(batch_size=2))
    with pytest.raises(ValueError, match=r"\(B, A\)"):
        c(np.zeros(7), make_state(batch_size=2))
    with pytest.raises(ValueError, match="2 envs"):
        Corrector(PhysVLAConfig.paper(), 1)(np.zeros((1, 7)), make_state(batch_size=2))


def test_invalid_state_and_nonfinite_action_pass_through_and_are_counted():
    st = make_state(batch_size=3, obj=(0.5, 0, 0.9))
    st.valid[1] = False
    raw = np.repeat(RAW, 3, axis=0)
    raw[2, 0] = np.nan
    c = Corrector(PhysVLAConfig.paper(), 3)
    with pytest.warns(RuntimeWarning, match="passing"):
        out = c(raw, st)
    np.testing.assert_array_equal(out[1], raw[1])
    np.testing.assert_array_equal(out[2], [0, 0, 0, 0, 0, 0, -1])  # the hold action: 0 deltas, gripper open
    assert out[0, 6] != raw[0, 6]  # env 0 is still corrected
    assert c.passthrough_counts == {"invalid_state": 1, "nonfinite_action": 1}
    assert c.guard_counts == {"held_nonfinite_action": 1}
    assert c.last.passthrough.tolist() == [False, True, True]


@pytest.mark.parametrize("weighting", ["joint_diag", "task_space"])
def test_singular_mass_matrix_passes_that_env_through(weighting):
    st = make_state(batch_size=2, obj=(0.5, 0, 0.9))
    st.M[1] = 0.0  # finite but not positive definite
    c = Corrector(PhysVLAConfig.paper(weighting=weighting), 2)
    raw = np.repeat(RAW, 2, axis=0)
    with pytest.warns(RuntimeWarning, match="singular_dynamics"):
        out = c(raw, st)
    np.testing.assert_array_equal(out[1], raw[1])
    assert out[0, 6] != raw[0, 6]  # env 0 still corrected
    assert c.passthrough_counts == {"singular_dynamics": 1}


# ------------------------------------------------------------------ properties
unit = st_.floats(-1.0, 1.0, allow_nan=False)
coord = st_.floats(-0.5, 0.5, allow_nan=False)


@settings(max_examples=150, deadline=None)
@given(
    a=st_.lists(unit, min_size=7, max_size=7),
    eef=st_.tuples(coord, coord, coord),
    obj=st_.tuples(coord, coord, coord),
    tgt=st_.tuples(coord, coord, coord),
    lift=st_.floats(-0.05, 0.3),
    mode=st_.sampled_from(MODES),
    el=st_.sampled_from(["soft", "gated", "off"]),
    weighting=st_.sampled_from(["joint_diag", "task_space"]),
    grip=st_.sampled_from(["blend", "veto"]),
    seed=st_.integers(0, 50),
)
def test_output_in_bounds_and_deviation_capped(a, eef, obj, tgt, lift, mode, el, weighting, grip, seed):
    cfg = PhysVLAConfig.paper(mode=mode, el_mode=el, weighting=weighting, gripper_rule=grip)
    st = make_state(eef=eef, obj=obj, target=tgt, lift=lift, seed=seed)
    raw = np.array([a])
    c = Corrector(cfg)
    for _ in range(3):  # several steps so the EMAs carry memory
        out = c(raw, st)
        assert out.shape == raw.shape
        assert np.isfinite(out).all() and (out >= -1).all() and (out <= 1).all()
        if mode in ("phys", "phys_el"):
            dev = np.abs(out - raw)[0]
            # eq. 2: |a - a_raw| = c |a_phys - a_raw| <= c (high - low), except the vetoed gripper
            limit = np.full(7, cfg.cap * 2.0 + 1e-12)
            if grip == "veto" and c.last.phase[0] == Phase.APPROACH:
                limit[6] = 2.0
            assert (dev <= limit).all()


@settings(max_examples=60, deadline=None)
@given(bad=st_.sampled_from([np.nan, np.inf, -np.inf]), idx=st_.integers(0, 6))
def test_nonfinite_actions_become_the_hold_action(bad, idx):
    c = Corrector(PhysVLAConfig.paper())
    first = c(RAW, make_state())  # a finite step: its gripper command is what the hold repeats
    raw = RAW.copy()
    raw[0, idx] = bad
    with pytest.warns(RuntimeWarning, match="non-finite"):
        out = c(raw, make_state())
    np.testing.assert_array_equal(out[0, :6], np.zeros(6))  # delta channels hold still
    assert out[0, 6] == first[0, 6]  # the gripper repeats its last command
    assert c.passthrough_counts["nonfinite_action"] == 1 and c.guard_counts["held_nonfinite_action"] == 1


def test_phase_caps_replace_the_cap_per_phase():
    st = make_state(eef=(0, 0, 1.0), obj=(0.01, -0.02, 0.95))  # grasp phase
    cand = RAW.copy()
    cand[0, :3] = 0.5 * np.array([0.2, -0.4, -1.0]) + 0.5 * RAW[0, :3]
    out = Corrector(PhysVLAConfig.paper(mode="phys", phase_caps=(0.0, 0.4, 0.0, 0.0)))(RAW, st)
    np.testing.assert_allclose(out, 0.6 * RAW + 0.4 * cand)
    off = Corrector(PhysVLAConfig.paper(mode="phys", phase_caps=(1.0, 0.0, 1.0, 1.0)))(RAW, st)
    np.testing.assert_array_equal(off, RAW)


def test_full_veto_with_height_vetoes_a_close_above_the_object_in_grasp():
    close = RAW.copy()
    close[0, 6] = 1.0  # robosuite: +1 closes
    cfg = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0,) * 4, gripper_rule="veto", veto_height_m=0.06)
    high = make_state(eef=(0.01, 0, 1.0), obj=(0.0, 0.0, 0.9))  # grasp phase, hand 10 cm above
    low = make_state(eef=(0.01, 0, 0.94), obj=(0.0, 0.0, 0.9))  # 4 cm above: a grasp can close
    far = make_state(eef=(0.3, 0, 0.94), obj=(0.0, 0.0, 0.9))  # approach: vetoed in full, cap 0 or not
    assert Corrector(cfg)(close, high)[0, 6] == -1.0
    assert Corrector(cfg)(close, low)[0, 6] == 1.0
    assert Corrector(cfg)(close, far)[0, 6] == -1.0
    assert Corrector(cfg.replace(veto_height_m=0.0))(close, high)[0, 6] == 1.0  # 0: approach only


def test_the_veto_never_opens_a_gripper_that_holds_when_told_so():
    """veto_reopen=False: the veto keeps an open gripper open but never opens a closed one (it may
    hold the object). The failure it fixes: a LIBERO bowl held by its rim hangs 0.060 m below the
    hand while the phase is still grasp; at the height veto's 0.06 m the veto opened the gripper."""
    close = RAW.copy()
    close[0, 6] = 1.0  # robosuite: +1 closes
    cfg = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0,) * 4, gripper_rule="veto", veto_height_m=0.06)
    low = make_state(eef=(0.01, 0, 0.94), obj=(0.0, 0.0, 0.9))  # grasp phase, 4 cm above: it closes
    lifting = make_state(eef=(0.01, 0, 0.9605), obj=(0.0, 0.0, 0.9))  # still grasp, 6.05 cm above
    for reopen, last_grip in ((True, -1.0), (False, 1.0)):
        for profile in (False, True):  # the one-call tick and the staged twin
            c = Corrector(cfg.replace(veto_reopen=reopen), profile=profile)
            assert c(close, low)[0, 6] == 1.0  # closed on the object
            assert c(close, lifting)[0, 6] == last_grip  # reopen: dropped; holds: kept closed
    held = Corrector(cfg.replace(veto_reopen=False))
    assert held(close, lifting)[0, 6] == -1.0  # never closed here: a close above the object is vetoed
    assert held(close, lifting)[0, 6] == -1.0  # and stays vetoed (the gripper was held open)
    far = make_state(eef=(0.3, 0, 0.94), obj=(0.0, 0.0, 0.9))  # approach, out of reach
    assert held(close, far)[0, 6] == -1.0


def test_the_height_veto_spares_a_close_begun_on_the_way_down_onto_the_object():
    """A close the policy begins in the grasp phase while the hand comes down fast enough to be at the veto height
    by the time the fingers shut (corrections/approach_veto.py timed_close) is timed to the descent: the height veto
    leaves it alone (MetaWorld's shelf-place policy closes ~10 cm above its block at ~0.8 m/s). One begun at rest
    stays vetoed step by step, also once the hand comes down."""
    close, open_ = RAW.copy(), RAW.copy()
    close[0, 6], open_[0, 6] = 1.0, -1.0  # robosuite: +1 closes

    def at(z, v_z):  # grasp phase, the hand z above the object's origin moving at v_z (m/s): J_pos[2] . qdot
        st = make_state(eef=(0.01, 0, 0.9 + z), obj=(0.0, 0.0, 0.9))
        st.J_pos[:], st.qdot[:] = 0.0, 0.0
        st.J_pos[0, 2, 0], st.qdot[0, 0] = 1.0, v_z
        return st

    cfg = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0,) * 4, gripper_rule="veto", veto_height_m=0.06,
                              veto_close_lead_s=0.1)
    off = Corrector(cfg.replace(veto_close_lead_s=0.0))  # off (every preset): the close is held as before
    assert off(close, at(0.10, -0.8))[0, 6] == -1.0
    for profile in (False, True):  # the one-call tick and the staged twin
        c = Corrector(cfg, profile=profile)
        assert c(close, at(0.10, -0.8))[0, 6] == 1.0  # 10 cm up, 8 cm down in 0.1 s: timed
        c.reset()
        assert c(close, at(0.10, -0.1))[0, 6] == -1.0  # descending slowly: vetoed
        assert c(close, at(0.09, -0.8))[0, 6] == -1.0  # the same close, the hand now fast: still vetoed
        assert c(close, at(0.05, -0.8))[0, 6] == 1.0  # below the veto height: as before
        c(open_, at(0.10, 0.0))  # the policy opens: the next close is judged afresh
        assert c(close, at(0.10, -0.8))[0, 6] == 1.0
        c.reset()
        assert c(close, at(0.30, -0.8))[0, 6] == -1.0  # too high to get there in time: vetoed


def test_veto_reach_spares_a_low_close_within_reach_of_a_rim():
    close = RAW.copy()
    close[0, 6] = 1.0  # robosuite: +1 closes
    cfg = PhysVLAConfig.paper(mode="phys", phase_caps=(0.0,) * 4, gripper_rule="veto", veto_height_m=0.06,
                        veto_reach_m=0.10)
    rim = make_state(eef=(0.0, -0.08, 0.935), obj=(0.0, 0.0, 0.9))  # approach (0.08 >= 0.06), 3.5 cm up
    beyond = make_state(eef=(0.0, -0.12, 0.935), obj=(0.0, 0.0, 0.9))  # out of the fingers' reach
    over = make_state(eef=(0.0, -0.08, 1.0), obj=(0.0, 0.0, 0.9))  # within reach but 10 cm above
    assert Corrector(cfg)(close, rim)[0, 6] == 1.0
    assert Corrector(cfg)(close, beyond)[0, 6] == -1.0
    assert Corrector(cfg)(close, over)[0, 6] == -1.0
    assert Corrector(cfg.replace(veto_reach_m=0.0))(close, rim)[0, 6] == -1.0  # 0: all of approach (paper)
    assert Corrector(cfg, profile=True)(close, rim)[0, 6] == 1.0  # the staged path agrees


def test_phase_ref_object_measures_the_place_distance_from_the_held_object():
    # lifted object 8 cm off the hand, right over the target; the hand itself is 8 cm away from it
    st = make_state(eef=(0.10, 0.0, 1.0), obj=(0.02, 0.0, 0.95), target=(0.02, 0.0, 0.9), lift=0.05)
    c_eef = Corrector(PhysVLAConfig.paper(mode="phys"))
    c_obj = Corrector(PhysVLAConfig.paper(mode="phys", phase_ref="object"))
    c_eef(RAW, st)
    c_obj(RAW, st)
    assert c_eef.last.phase[0] == Phase.TRANSPORT and c_eef.last.d_tgt_xy[0] == pytest.approx(0.08)
    assert c_obj.last.phase[0] == Phase.PLACE and c_obj.last.d_tgt_xy[0] == pytest.approx(0.0)


@pytest.mark.parametrize("mode", ["phys", "phys_el", "temporal"])
def test_a_stream_in_one_call_equals_the_stream_in_steps(mode):
    """correct_stream's compiled call (episode resets, the tick) against its step-by-step path
    (reset where episode_step went back or on first sight, then correct_packed): the same actions
    over episodes of different lengths per env, non-finite and out-of-bounds actions included."""
    cfg = PhysVLAConfig.paper(mode=mode, cap=1.0)
    one, steps = Corrector(cfg, 3), Corrector(cfg, 3)
    rng = np.random.default_rng(5)
    counters = np.zeros(3)
    for t in range(120):
        for i, length in enumerate((25, 40, 61)):
            if t and t % length == 0:
                counters[i] = 0
        st = make_state(batch_size=3, obj=(0.02 * (30 - t % 30), 0.0, 0.9), seed=t)
        st.episode_step[:] = counters
        flat = st.pack()
        a = rng.uniform(-1.5, 1.5, (3, 7))
        if t % 17 == 0:
            a[1, 2] = np.nan
        out1 = one.correct_stream(a.astype(np.float32), flat)
        a_f = np.asfortranarray(a.astype(np.float32)).astype(np.float64)  # not C-contiguous: in steps
        assert not a_f.flags.c_contiguous
        out2 = steps.correct_stream(a_f, flat)
        assert out1.dtype == np.float32 and out2.dtype == np.float64
        np.testing.assert_array_equal(out1, out2.astype(np.float32))
        assert np.isfinite(out1).all() and np.abs(out1).max() <= 1.0
        counters += 1
    assert one.guard_counts == steps.guard_counts and one.steps == steps.steps


@pytest.mark.slow
def test_arrays_the_direct_call_cannot_take_go_in_steps_with_the_same_output():
    """correct_stream calls stream_tick's compiled overload directly (no numba dispatch, no type
    check): a read-only or misaligned action, or a read-only state, must take the checked path in
    steps, with the same output as the direct call."""
    from lerobot_physvla.core.config import PRESETS
    from lerobot_physvla.core.direct_call import direct_entry
    from lerobot_physvla.core.tick import stream_tick

    direct, checked = Corrector(PRESETS["default"], 2), Corrector(PRESETS["default"], 2)
    rng = np.random.default_rng(3)
    for t in range(40):
        st = make_state(batch_size=2, obj=(0.02 * (30 - t % 30), 0.0, 0.9), seed=t)
        st.episode_step[:] = t
        flat = st.pack()
        a = rng.uniform(-1.5, 1.5, (2, 7)).astype(np.float32)
        if t % 3 == 0:
            odd = np.frombuffer(bytearray(a.nbytes + 1), dtype=np.float32, offset=1, count=a.size).reshape(a.shape)
            odd[:] = a
            assert not odd.flags.aligned
        else:
            odd = a.copy()
            odd.flags.writeable = False
        ro_flat = flat.copy()
        ro_flat.flags.writeable = t % 2 == 0
        out1, out2 = direct.correct_stream(a, flat), checked.correct_stream(odd, ro_flat)
        np.testing.assert_array_equal(out1, out2.astype(np.float32))
    # the direct entry is the dispatcher's own compiled code: same result on the same arrays
    c1, c2 = Corrector(PRESETS["default"], 2), Corrector(PRESETS["default"], 2)
    none = np.zeros((0, 0, 0))
    call = direct_entry(stream_tick, a, flat, c1._fws, c1._iws, c1._bws, none, 0)
    r1, e1 = call(a, flat, c1._fws, c1._iws, c1._bws, none, 0)
    r2, e2 = stream_tick(a, flat, c2._fws, c2._iws, c2._bws, none, 0)
    np.testing.assert_array_equal(r1, r2)
    assert e1 == e2


def test_the_shipped_default_lets_go_of_a_still_hold_over_the_target_and_the_arm_preset_does_not():
    """Candidate 10's traced failure (a weak chunked ACT holds the bowl 2 cm above the plate, still,
    gripper closed, to the end): the default opens after assist_steps steps; `arm` never does."""
    from lerobot_physvla.core.config import PRESETS

    # the bowl carried to the plate: 2.1 cm above the plate's origin, 2.5 cm above its own rest
    st = make_state(eef=(0.07, 0.15, 0.975), obj=(0.074, 0.19, 0.923), target=(0.066, 0.197, 0.902), lift=0.025)
    hold = np.array([[0.01, 0.0, -0.01, 0.0, 0.0, 0.0, 0.87]])  # still, closed (robosuite: + = close)
    for name, opens_at in (("default", PRESETS["default"].assist_steps), ("arm", None)):
        c = Corrector(PRESETS[name])
        grip = [c(hold, st)[0, 6] for _ in range(15)]
        assert all(c.last.phase == Phase.PLACE)
        if opens_at is None:
            assert grip == [0.87] * 15, name
        else:
            assert grip[: opens_at - 1] == [0.87] * (opens_at - 1) and grip[opens_at - 1:] == [-1.0] * (16 - opens_at)


def test_the_shipped_default_lifts_a_still_rim_hold_and_the_arm_preset_does_not():
    """Candidate 15's traced failure (a weak single-step ACT closes on the bowl's rim, the fingers stop
    13 mm apart, and holds it still, z command -0.02, to the end): the default raises z to
    lift_assist_u from the assist_steps-th step on, every other channel the policy's; `arm` never."""
    from lerobot_physvla.core.config import PRESETS

    st = make_state(eef=(0.019, -0.047, 0.924), obj=(0.0, 0.0, 0.898), target=(0.2, 0.1, 0.9))
    st.gripper[:] = 0.013
    hold = np.array([[0.02, 0.0, -0.02, 0.0, 0.0, 0.0, 1.0]])  # still, closed (robosuite: + = close)
    for name, lifts_at in (("default", PRESETS["default"].assist_steps), ("arm", None)):
        c = Corrector(PRESETS[name])
        outs = [c(hold, st)[0] for _ in range(15)]
        assert all(c.last.phase == Phase.GRASP)
        z = [o[2] for o in outs]
        if lifts_at is None:
            assert z == [-0.02] * 15, name
        else:
            assert z[: lifts_at - 1] == [-0.02] * (lifts_at - 1) and z[lifts_at - 1:] == [0.5] * (16 - lifts_at)
        assert all(np.array_equal(np.delete(o, 2), np.delete(hold[0], 2)) for o in outs), name


def test_the_shipped_default_pulls_a_settled_miss_onto_the_rim_and_the_arm_preset_does_not():
    """Candidate 17's traced failure (the jitter expert's aim error sets its rim grasp 9 cm from the
    bowl's origin, outside the wall; it hovers there and closes on nothing): the default leaves the
    first steps (the hand has not been seen settled), then commands x, y toward the rim point on the
    hand's own line, z and the gripper the policy's; `arm` executes the policy's action."""
    from lerobot_physvla.core.config import PRESETS
    from lerobot_physvla.core.corrections.rim_guide import RIM_SETTLE_STEPS

    st = make_state(eef=(0.031, -0.085, 0.968), obj=(0.0, 0.0, 0.898), target=(0.2, 0.1, 0.9))
    hover = np.array([[0.1, -0.05, -0.3, 0.0, 0.0, 0.0, -1.0]])  # open, a small noisy move
    for name in ("default", "arm"):
        c = Corrector(PRESETS[name])
        outs = [c(hover, st)[0] for _ in range(RIM_SETTLE_STEPS + 3)]
        assert all(c.last.phase == Phase.APPROACH)
        assert all(np.array_equal(o, hover[0]) for o in outs[:RIM_SETTLE_STEPS]), name
        for o in outs[RIM_SETTLE_STEPS:]:
            if name == "arm":
                np.testing.assert_array_equal(o, hover[0])
            else:
                assert o[0] < 0 < o[1], o  # toward the bowl, x +3.1 -> +1.6 cm, y -8.5 -> -4.4 cm
                np.testing.assert_array_equal(o[2:], hover[0, 2:])


def test_a_state_marking_its_task_outside_the_model_passes_through_as_unsupported_goal():
    import warnings

    from lerobot_physvla.core.state import UNSUPPORTED_GOAL_VALID, PhysState

    s = PhysState.empty(1, 7)
    s.valid[:], s.dt[:] = UNSUPPORTED_GOAL_VALID, 0.05
    a = np.array([[0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]])
    c = Corrector(PhysVLAConfig())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        np.testing.assert_array_equal(c(a, s), a)
    assert c.passthrough_counts == {"unsupported_goal": 1}
