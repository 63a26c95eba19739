"""Episode splitting of the recorder: batches, successes, frozen sub-envs, executed-action echo."""

import json

import numpy as np

from lerobot_physvla.core.config import PhysVLAConfig
from lerobot_physvla.core.corrector import Corrector
from lerobot_physvla.core.state import packed_size
from lerobot_physvla.diagnostics import EpisodeRecorder

from conftest import make_state


def feed(rec, corr, steps, success, executed):
    st = make_state(batch_size=2, obj=(0.5, 0.0, 0.9))  # approach
    st.episode_step[:] = steps
    extra = np.zeros((2, 9))
    extra[:, 1] = success
    extra[:, 2:] = executed
    raw = np.full((2, 7), 0.1)
    out = corr(raw, st)
    rec(raw, out, st.pack(), extra, corr, 1e-5)


def test_recorder_splits_episodes_and_stops_at_success(tmp_path):
    rec, corr = EpisodeRecorder(horizon=10), Corrector(PhysVLAConfig.paper(), 2)
    feed(rec, corr, [0, 0], [0, 0], 0.0)
    feed(rec, corr, [1, 1], [0, 0], 0.5)  # both executed 0.5 at step 0
    feed(rec, corr, [2, 2], [1, 0], 0.6)  # env 0 succeeded with its step-1 action
    feed(rec, corr, [0, 3], [0, 0], 0.7)  # env 0 autoreset (ignored until the next batch); env 1 goes on
    feed(rec, corr, [0, 3], [0, 0], 0.7)  # env 1 frozen: same step replayed, ignored
    feed(rec, corr, [0, 0], [0, 0], 0.0)  # a new batch: both envs start new episodes
    recs = rec.records()
    assert [(r["env_index"], r["steps"], r["success"]) for r in recs] == [(0, 2, True), (1, 4, False), (0, 1, False), (1, 1, False)]
    assert recs[0]["executed_actions"][0] == [0.5] * 7 and recs[0]["executed_actions"][1] == [0.6] * 7
    assert recs[0]["efficiency"] == 0.8 and recs[1]["efficiency"] == 0.0
    s = rec.summary()
    assert s["episodes"] == 4 and s["success_rate"] == 0.25
    # raw gripper 0.1 in approach: the veto (through the 5 % cap) changes it at every approach step
    assert s["veto_fire_rate"] == 1.0 and s["el_fire_rate"] == 1.0  # phys_el soft: Branch B always on
    rec.write(tmp_path, config={"mode": "phys_el"})
    assert (tmp_path / "physvla_episodes.jsonl").read_text().count("\n") == 4


def test_recording_grows_past_its_first_capacity_and_keeps_states(tmp_path):
    rec, corr = EpisodeRecorder(save_states=True), Corrector(PhysVLAConfig.paper(), 2)
    n = 2 * rec_capacity() + 10  # one episode per env, longer than twice the first capacity
    for t in range(n):
        feed(rec, corr, [t, t], [0, 0], 0.1)
    eps = rec.episodes
    assert [len(e.raw) for e in eps] == [n, n] and eps[0].states.shape == (n, packed_size(7))
    np.testing.assert_array_equal(eps[1].states[:, 1], np.arange(n))  # episode_step column of the packed rows
    assert rec.summary()["steps"] == 2 * n
    rec.write(tmp_path)
    assert np.load(tmp_path / "physvla_states.npz")["ep1_states"].shape[0] == n


def rec_capacity() -> int:
    from lerobot_physvla.diagnostics import _Segment

    return _Segment.CAPACITY


def test_a_listener_call_copies_what_it_keeps():
    """The step hands the recorder arrays it reuses (the corrector's diag buffer): a record must
    not change when they are overwritten."""
    rec, corr = EpisodeRecorder(), Corrector(PhysVLAConfig.paper(), 2)
    feed(rec, corr, [0, 0], [0, 0], 0.0)
    phase0 = rec.episodes[0].phase.copy()
    corr.diag_buffer[:] = 7.0
    assert (rec.episodes[0].phase == phase0).all()


def _run_batches(rec, corr, batches: int, steps: int) -> None:
    rng = np.random.default_rng(0)
    for _ in range(batches):
        for t in range(steps):
            st = make_state(batch_size=2, obj=(0.02 * (steps - t), 0.0, 0.9), seed=t)  # approach, then grasp
            st.episode_step[:] = t
            raw = rng.uniform(-1, 1, (2, 7))
            rec(raw, corr(raw, st), st.pack(), None, corr, 1e-5 * (1 + t % 3))


def test_finished_batches_are_compacted_with_the_same_records_and_flat_memory():
    from lerobot_physvla.core.config import LAYOUTS

    lay = LAYOUTS["libero_osc_pose"]
    full = EpisodeRecorder(layout=lay, keep_steps=None)
    compact = EpisodeRecorder(layout=lay, keep_steps=3)
    c1, c2 = Corrector(PhysVLAConfig.paper(), 2), Corrector(PhysVLAConfig.paper(), 2)
    _run_batches(full, c1, 2, 30)
    _run_batches(compact, c2, 2, 30)
    rows_after_two = compact._seg.raw.nbytes
    _run_batches(compact, c2, 40, 30)  # 20x more steps: the recording's rows are reused
    assert compact._seg.raw.nbytes == rows_after_two and compact._seg.n == 30
    _run_batches(full, c1, 40, 30)
    a, b = full.records(), compact.records()
    assert len(a) == len(b) == 84
    for ra, rb in zip(a, b):
        assert ("raw_actions" in rb) == (rb["episode"] < 3)  # per-step arrays: the first 3 episodes only
        for key, value in rb.items():
            assert ra[key] == value or (value != value and ra[key] != ra[key]), key
    assert [e.raw.shape[0] for e in compact.episodes[:4]] == [30, 30, 30, 0]
    assert json.dumps(full.summary(), sort_keys=True) == json.dumps(compact.summary(), sort_keys=True)  # NaN-aware
    # the env's own success, applied after the batch was compacted, still counts (and moves efficiency)
    compact.horizon = full.horizon = 60
    for rec in (full, compact):
        rec.apply_env_successes({-1: [True] + [False] * 83})
    assert compact.records()[0]["success"] and compact.records()[0]["efficiency"] == 0.5
    assert json.dumps(full.summary(), sort_keys=True) == json.dumps(compact.summary(), sort_keys=True)  # NaN-aware



def test_a_batch_ended_between_rollouts_compacts_there_with_the_same_records():
    """lerobot-eval's hook ends each rollout batch before the next rollout starts: the next batch's
    first call then compacts nothing (the 1-2 ms per episode leave the control tick), and the
    records are those of a recorder that compacts in that first call."""
    from lerobot_physvla.core.config import LAYOUTS

    lay = LAYOUTS["libero_osc_pose"]
    in_tick, between = EpisodeRecorder(layout=lay, keep_steps=3), EpisodeRecorder(layout=lay, keep_steps=3)
    c1, c2 = Corrector(PhysVLAConfig.paper(), 2), Corrector(PhysVLAConfig.paper(), 2)
    log = []
    finish = between._finish
    between._finish = lambda: (log.append("finish"), finish())[1]
    for _ in range(5):
        _run_batches(in_tick, c1, 1, 30)
        log.append("end")
        between.end_batch()  # the hook's call before a rollout (nothing recorded yet the first time)
        log.append("rollout")
        _run_batches(between, c2, 1, 30)
    log.append("end")
    between.end_batch()
    # each compaction right after an end_batch, none inside a call of the recorder
    assert log == ["end", "rollout"] + ["end", "finish", "rollout"] * 4 + ["end", "finish"]
    a, b = in_tick.records(), between.records()
    assert len(a) == len(b) == 10
    for ra, rb in zip(a, b):
        for key, value in rb.items():
            assert ra[key] == value or (value != value and ra[key] != ra[key]), key
    assert json.dumps(in_tick.summary(), sort_keys=True) == json.dumps(between.summary(), sort_keys=True)
