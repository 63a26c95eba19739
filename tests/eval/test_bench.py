import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval" / "bench"))
import training as bench_training  # noqa: E402


def test_log_periods_reads_lerobot_train_log_lines_through_progress_bars():
    # lerobot-train's own log lines, as they reach a captured stderr between tqdm redraws
    text = ("Training:   3%|▎ | 200/6000 [00:57<32:14,  3.00step/s]\rINFO 2026-11-23 07:32:20 ot_train.py:641 step:200 "
            "smpl:6K ep:54 epch:0.12 loss:1.366 grdn:21.242 lr:3.0e-04 updt_s:0.172 data_s:0.111 smp/s:113\n"
            "Training:   7%|▋ | 400/6000\rINFO 2026-11-23 07:33:20 ot_train.py:641 step:400 smpl:13K ep:107 "
            "epch:0.25 loss:0.223 grdn:2.880 lr:3.0e-04 updt_s:0.025 data_s:0.055 smp/s:398 l1_loss:0.223\n")
    assert bench_training.log_periods(text) == [(0.172, 0.111), (0.025, 0.055)]
    assert bench_training.log_periods("Training: 100%| 8000/8000\nEnd of training\n") == []


def _path(*points, step=0.01):
    """Rows of xyz through `points`, at most `step` metres apart (a hand moves about a centimetre a step)."""
    rows = [np.asarray(points[0], float)]
    for a, b in zip(points, points[1:]):
        n = max(int(np.ceil(np.linalg.norm(np.subtract(b, a)) / step)), 1)
        rows += [np.asarray(a, float) + (np.subtract(b, a)) * k / n for k in range(1, n + 1)]
    return np.array(rows)


def _trace(hand, obj, target):
    """Rows (hand xyz, object xyz, target xyz) per step: a fixed target beside the hand's and object's paths."""
    return np.concatenate([hand, obj, np.tile(np.asarray(target, float), (len(hand), 1))], axis=1)


def test_failure_modes_sorts_an_episode_by_what_its_object_did():
    import failure_modes as fm

    tgt, table = (0.3, 0.0, 0.9), (0.0, 0.0, 0.9)
    rest = _path(table, table)
    assert fm.outcome(True, _trace(_path((0, 0.3, 1.2), (0, 0.3, 1.2)), rest, tgt)) == "success"  # its own success wins
    assert fm.outcome(False, _trace(_path((0, 0.3, 1.2), (0, 0.3, 1.2)), rest, tgt)) == "never reached"
    assert fm.outcome(False, _trace(_path((0, 0.01, 0.92), (0, 0.01, 0.92)), rest, tgt)) == "reached, not lifted"
    dropped = _path(table, (0, 0, 0.95), (0.1, 0, 0.95), (0.1, 0, 0.9))
    assert fm.outcome(False, _trace(dropped, dropped, tgt)) == "lifted, dropped"
    held = _path(table, (0, 0, 0.95), (0.2, 0, 0.97))
    assert fm.outcome(False, _trace(held, held, tgt)) == "lifted, held at the end"
    on_target = _path(table, (0, 0, 0.95), (0.28, 0, 0.95), (0.28, 0, 0.9))
    assert fm.outcome(False, _trace(on_target, on_target, tgt)) == "on target, no success"
    # a bowl (radius 7 cm, top 5 cm above its origin) whose rim the hand reaches 6 cm from its centre: reached with
    # its extents, never reached as a point; lifted by the rim, it is lifted either way
    rim = _path((0.06, 0, 0.96), (0.06, 0, 0.96))
    bowl = np.concatenate([_trace(rim, rest, tgt), np.tile([0.07, 0.05], (len(rim), 1))], axis=1)
    assert fm.outcome(False, bowl) == "reached, not lifted"
    assert fm.outcome(False, _trace(rim, rest, tgt)) == "never reached"
    carried = _path(table, (0, 0, 0.95), (0.1, 0, 0.95), (0.1, 0, 0.9))
    assert fm.outcome(False, _trace(carried + [0.06, 0, 0.06], carried, tgt)) == "lifted, dropped"
    # a two-object goal: the first object carried off, then the corrector tracks a second one (a jump of its tracked
    # position) that the hand never reaches: the episode is judged by the second object
    first = _path(table, (0, 0, 0.95), (0.3, 0, 0.95))
    obj = np.concatenate([first, _path((0.5, 0.5, 0.9), (0.5, 0.5, 0.9))])
    hand = np.concatenate([first, _path((0.3, 0, 0.95), (0.3, 0, 0.95))])
    assert fm.outcome(False, _trace(hand, obj, tgt)) == "never reached"


def test_the_steer_probe_pulls_a_settled_low_hand_toward_the_object_and_refuses_the_studys_blocks():
    """eval/bench/steer_probe.py: the probe's pull (its module doc) on top of the default's action."""
    from types import SimpleNamespace

    import pytest

    import steer_probe

    from lerobot_physvla.core.config import LIBERO_OSC_POSE as lay  # 7-D, gripper 6, 0.05 m per unit

    class Inner:
        layout = lay
        passthrough_counts: dict = {}

        def __init__(self):
            self.last = SimpleNamespace(phase=np.array([0]), lift=np.array([0.0]))

        def __call__(self, raw, st):
            return np.clip(raw, -1, 1)

        def reset(self):
            pass

    def state(eef, obj=(0.0, 0.0, 0.0)):
        return SimpleNamespace(eef_pos=np.array([eef], float), obj_pos=np.array([obj], float))

    def run(eef_path, grip=-1.0):
        c = steer_probe.SteeredCorrector(Inner())
        c.reset()
        raw = np.zeros((1, 7))
        raw[0, 6] = grip
        out = [c(raw, state(e)) for e in eef_path]
        return out[-1][0], c.pulled

    low_far = [(0.2, 0.0, 0.05)] * 6  # 20 cm from the object, 5 cm above it: settled at the sixth step
    out, pulled = run(low_far)
    assert pulled == 1 and out[0] == -1.0 and out[1] == 0.0  # full pull toward -x (20 cm > one unit's 5 cm)
    assert run([(0.2, 0.0, 0.30)] * 7)[1] == 0  # hovering high: left alone
    assert run([(0.2 - 0.02 * k, 0.0, 0.05) for k in range(7)])[1] == 0  # still moving, never settled: left alone
    assert run([(0.02, 0.01, 0.05)] * 7, grip=1.0)[1] == 0  # closing at the object: left to the policy
    assert run(low_far, grip=1.0)[1] == 1  # closing far from it (the veto holds it open there): pulled
    with pytest.raises(SystemExit, match="held out or confirmation"):
        steer_probe.main(["--suite", "libero_object_swap", "--init", "5-6"])
    with pytest.raises(SystemExit, match="held out or confirmation"):
        steer_probe.main(["--suite", "libero_object", "--init", "42"])
