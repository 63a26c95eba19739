"""The adaptive low-pass: off for a smooth policy, strong for a jittery one, never on the gripper."""

import numpy as np

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.lowpass import LP_ACTIVE, LP_NDIFF, LP_WIN, N_LP_MEM, adaptive_lowpass
from lerobot_physvla.core.state import OK

from conftest import make_state

CAPS_OFF = (0.0, 0.0, 0.0, 0.0)


def _run(actions, **cfg):
    c = Corrector(PhysVLAConfig.paper(mode="phys", phase_caps=CAPS_OFF, lowpass="adaptive", **cfg))
    st = make_state(obj=(0.5, 0.0, 0.9))  # approach phase
    return np.array([c(a[None], st)[0] for a in actions])


def test_a_smooth_policy_is_executed_as_it_is():
    t = np.arange(60)
    raw = np.zeros((60, 7))
    raw[:, 0] = 0.5 * np.sin(t / 10.0)  # smooth: step-to-step changes ~0.05, noise estimate < lo
    raw[:, 6] = -1.0
    np.testing.assert_array_equal(_run(raw), raw)


def test_a_jittery_policy_is_smoothed_on_the_position_channels_only():
    rng = np.random.default_rng(0)
    raw = np.zeros((200, 7))
    raw[:, :2] = rng.normal(0.0, 0.3, (200, 2))
    raw[:, 3:6] = rng.normal(0.0, 0.3, (200, 3))
    raw[:, 6] = np.where(rng.uniform(size=200) < 0.5, -1.0, 1.0)
    raw = np.clip(raw, -1.0, 1.0)
    out = _run(raw, lowpass_alpha_max=0.8)
    # after the roughness estimate settles, the x, y jitter is cut (alpha -> alpha_max = 0.8:
    # an EMA keeps sqrt((1 - a) / (1 + a)) = 0.33 of white noise's std)
    assert out[50:, :2].std() < 0.45 * raw[50:, :2].std()
    np.testing.assert_array_equal(out[:, 2], raw[:, 2])  # z was smooth (all zero): untouched
    np.testing.assert_array_equal(out[:, 3:], raw[:, 3:])  # rotation and gripper never filtered
    assert np.all(np.abs(out) <= 1.0)


def test_only_in_the_listed_phases():
    rng = np.random.default_rng(1)
    raw = np.zeros((100, 7))
    raw[:, :2] = rng.normal(0.0, 0.3, (100, 2))
    np.testing.assert_array_equal(_run(raw, lowpass_phases="grasp,transport"), raw)  # state: approach
    assert not np.array_equal(_run(raw, lowpass_phases="approach"), raw)


def test_memory_moves_only_on_commit_and_a_pass_through_breaks_the_history():
    mem = np.zeros((1, N_LP_MEM))
    out = np.full((1, 7), 0.5)
    pos, mask = np.array([0, 1, 2]), np.ones(4, np.int64)
    args = (np.zeros(1, np.int8), np.array([OK], np.int8), pos, mask, 0.8, 0.05, 0.2)
    # rows, eef offset, absolute, m/unit, target space, speed, robust roughness, lag compensation
    where = (np.zeros((1, 8)), 0, np.zeros(7, np.bool_), 0.05, False, 0.0, True, False)
    adaptive_lowpass(out.copy(), out, *args, mem, False, np.zeros(1), *where)
    assert not mem.any()
    adaptive_lowpass(out.copy(), out, *args, mem, True, np.zeros(1), *where)
    assert mem[0, LP_ACTIVE] == 1.0
    bad = (args[0], np.array([1], np.int8), *args[2:])
    adaptive_lowpass(out.copy(), out, *bad, mem, True, np.zeros(1), *where)
    assert mem[0, LP_ACTIVE] == 0.0 and mem[0, LP_NDIFF] == 0.0


def _closed_loop(space: str | None, steps: int = 300, seed: int = 0, **cfg) -> tuple[np.ndarray, np.ndarray]:
    """A goal-seeking policy in a loop: a = 0.6 (goal - x) / 0.05 + N(0, 0.3) on x, y (the scripted
    expert's gain and the jitter expert's noise), executed by a perfect delta controller
    (x += a 0.05 m). Returns the positions (steps, 2) and the executed actions (steps, 2)."""
    rng = np.random.default_rng(seed)
    c = None if space is None else Corrector(PhysVLAConfig.paper(
        mode="phys", phase_caps=CAPS_OFF, lowpass="adaptive", lowpass_space=space, lowpass_alpha_max=0.6, **cfg))
    x, xs, acts = np.array([0.10, -0.08]), [], []
    for _ in range(steps):
        raw = np.zeros(7)
        raw[:2] = np.clip(0.6 * (0.0 - x) / 0.05 + rng.normal(0.0, 0.3, 2), -1.0, 1.0)
        st = make_state(eef=(x[0], x[1], 1.0), obj=(0.5, 0.0, 0.9))  # approach phase
        a = raw if c is None else c(raw[None], st)[0]
        x = x + a[:2] * 0.05
        xs.append(x.copy())
        acts.append(a[:2].copy())
    return np.array(xs), np.array(acts)


def test_in_target_space_a_closed_loop_settles_where_filtering_increments_rings():
    # the jitter expert's grasp approach under alpha 0.6 on its increments stalled short of the
    # grasp point (docs/method.md); filtering the commanded target keeps the loop first order
    for seed in range(3):
        x_raw, a_raw = _closed_loop(None, seed=seed)
        x_act, _ = _closed_loop("action", seed=seed)
        x_tgt, a_tgt = _closed_loop("target", seed=seed)
        err = {k: np.sqrt((v[50:] ** 2).mean()) for k, v in (("raw", x_raw), ("action", x_act), ("target", x_tgt))}
        assert err["target"] < 0.8 * err["raw"]  # the noise on the position is averaged
        assert err["target"] < 0.8 * err["action"]  # and the correction is not delayed into ringing
        # the executed motion is smoother than the policy's own
        assert np.abs(np.diff(a_tgt[50:], axis=0)).mean() < 0.7 * np.abs(np.diff(a_raw[50:], axis=0)).mean()


def test_target_space_is_the_action_space_on_an_absolute_layout():
    from lerobot_physvla.core.config import ActionLayout

    lay = ActionLayout(dim=7, pos=(0, 1, 2), rot=(3, 4, 5), gripper=6, metres_per_unit=0.05, absolute=True)
    rng = np.random.default_rng(3)
    raw = np.clip(rng.normal(0.0, 0.3, (80, 7)), -1.0, 1.0)
    outs = {}
    for space in ("action", "target"):
        c = Corrector(PhysVLAConfig.paper(mode="phys", layout=lay, phase_caps=CAPS_OFF, lowpass="adaptive",
                                    lowpass_space=space))
        st = make_state(eef=(0.2, -0.1, 1.0), obj=(0.5, 0.0, 0.9))
        outs[space] = np.array([c(a[None], st)[0] for a in raw])
    np.testing.assert_array_equal(outs["action"], outs["target"])
    assert not np.array_equal(outs["target"], raw)


def test_speed_fading_keeps_a_fast_move_at_the_policy_s_speed():
    # target space trails a constant-speed move (executed at (1 - alpha) of the commanded speed);
    # with lowpass_speed_hi the smoothing fades as the intended speed nears it
    def travelled(**cfg) -> tuple[float, float]:
        rng = np.random.default_rng(4)
        c = Corrector(PhysVLAConfig.paper(mode="phys", phase_caps=CAPS_OFF, lowpass="adaptive", lowpass_space="target",
                                    lowpass_alpha_max=0.6, **cfg))
        x = commanded = 0.0
        for _ in range(40):
            raw = np.zeros(7)
            raw[0] = np.clip(0.9 + rng.normal(0.0, 0.3), -1.0, 1.0)  # a fast, noisy move along x
            x += c(raw[None], make_state(eef=(x, 0.0, 1.0), obj=(5.0, 0.0, 0.9)))[0, 0] * 0.05
            commanded += raw[0] * 0.05
        return x, commanded

    x, commanded = travelled()
    assert x < 0.7 * commanded  # trails
    x, commanded = travelled(lowpass_speed_hi=1.0)
    assert x > 0.85 * commanded  # keeps pace
    x, commanded = travelled(lowpass_lag="compensate")  # leads by alpha / (1 - alpha) of the intended speed
    assert 0.9 * commanded < x < 1.1 * commanded


def test_lag_compensation_keeps_most_of_the_smoothing_in_a_closed_loop():
    # the lead follows a slow EMA of the policy's increments: the executed position's jerk (mean
    # |third difference|) stays well below the unfiltered loop's
    def jerk(x: np.ndarray) -> float:
        return float(np.abs(np.diff(x[50:], n=3, axis=0)).mean())

    for seed in range(3):
        raw = jerk(_closed_loop(None, seed=seed)[0])
        trail = jerk(_closed_loop("target", seed=seed)[0])
        lead = jerk(_closed_loop("target", seed=seed, lowpass_lag="compensate")[0])
        assert trail < lead < 0.5 * raw


def _chunked(steps: int = 120, jump: float = 0.5) -> np.ndarray:
    """A chunked policy's stream: constant increments within each chunk of 10, a jump of `jump`
    action units between chunks (x), y still, gripper closed."""
    raw = np.zeros((steps, 7))
    raw[:, 0] = np.where((np.arange(steps) // 10) % 2 == 0, 0.2, 0.2 + jump)
    raw[:, 6] = -1.0
    return raw


def test_the_median_roughness_leaves_a_chunked_policy_alone_and_still_smooths_jitter():
    raw = _chunked()
    # the EMA of squared changes reads each chunk boundary as noise (0.22 x the jump, above lo = 0.05)
    assert not np.array_equal(_run(raw, lowpass_space="target"), raw)
    # two large second differences in nine: the median stays 0
    np.testing.assert_array_equal(_run(raw, lowpass_space="target", lowpass_rough="median"), raw)
    rng = np.random.default_rng(6)
    jitter = np.zeros((120, 7))
    jitter[:, :2] = np.clip(rng.normal(0.0, 0.3, (120, 2)), -1.0, 1.0)
    out = _run(jitter, lowpass_rough="median", lowpass_alpha_max=0.8)
    assert out[30:, :2].std() < 0.5 * jitter[30:, :2].std()


def test_the_median_roughness_estimates_white_noise_std():
    from lerobot_physvla.core.lowpass import robust_roughness

    rng = np.random.default_rng(7)
    est = []
    for _ in range(400):
        d2 = np.diff(rng.normal(0.0, 0.3, 12), n=2)  # 10 second differences of white noise of std 0.3
        row = np.zeros(N_LP_MEM)
        row[LP_NDIFF] = 10.0  # nine already in the window, one more this step
        row[LP_WIN:LP_WIN + 9] = np.abs(d2[:9])
        est.append(robust_roughness(row, 0, d2[9], True, np.empty(9)))
    assert abs(np.median(est) - 0.3) < 0.05


def test_a_target_space_output_stays_inside_the_bounds_when_the_hand_jumps():
    # the filtered target minus the measured hand: a hand reported 4 action units away every other
    # step (a jumping state source) took the emitted action to |2.07| before the safety net clipped
    # corrected rows too
    c = Corrector(PhysVLAConfig.paper(mode="phys", phase_caps=CAPS_OFF, lowpass="adaptive", lowpass_space="target",
                                lowpass_alpha_max=0.6))
    rng = np.random.default_rng(0)
    outs = []
    for t in range(200):
        raw = np.zeros(7)
        raw[:2] = np.clip(rng.normal(0.0, 0.5, 2), -1.0, 1.0)
        outs.append(c(raw[None], make_state(eef=(0.2 * (t % 2 == 0), 0.0, 1.0), obj=(5.0, 0.0, 0.9)))[0])
    outs = np.asarray(outs)
    assert np.abs(outs).max() <= 1.0
    assert np.abs(outs).max() == 1.0  # the filter did push past the bounds: the clip was needed
