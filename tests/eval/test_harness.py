"""The evaluation harness: a unit writes its records atomically and a re-run skips it (resume)."""

import json
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "eval"))
from harness import Unit, run_units, seed_blocks  # noqa: E402

from lerobot_physvla import metrics  # noqa: E402
from lerobot_physvla.core.config import PhysVLAConfig  # noqa: E402


def test_seed_blocks_cover_every_seed_once():
    assert seed_blocks(7, 3) == [(0, 3), (3, 3), (6, 1)]


@pytest.mark.slow
def test_units_run_once_and_resume(tmp_path):
    unit = Unit("expert_clean", "phys_el", PhysVLAConfig.paper(mode="phys_el").to_dict(), task_id=0, first_seed=0, episodes=1)
    records, _ = run_units([unit], tmp_path, workers=1)
    path = tmp_path / "units" / f"{unit.key}.json"
    stamp = path.stat().st_mtime_ns
    (rec,) = records
    assert rec["success"] and rec["steps"] < 280  # the clean expert solves task 0, init state 0
    assert 0 < rec["precision"] <= 1 and rec["el_fire_rate"] == 1.0 and rec["t_us_p50"]["total"] > 0
    # how much the corrector did: phys_el's soft Branch B changes every step a little; baseline changes none
    assert rec["changed_fraction"] > 0.5 and 0 < rec["change_norm"] < rec["action_norm"]
    base = Unit("expert_clean", "baseline", PhysVLAConfig.paper(mode="baseline").to_dict(), task_id=0, first_seed=0,
                episodes=1)
    (b,), _ = run_units([base], tmp_path, workers=1)
    assert b["changed_fraction"] == 0.0 and b["change_norm"] == 0.0 and b["action_norm"] > 0
    again, _ = run_units([unit], tmp_path, workers=1)
    assert again == records and path.stat().st_mtime_ns == stamp  # resumed: not re-run
    assert json.loads(path.read_text())["unit"]["backbone"] == "expert_clean"
    assert metrics.wilson_interval(1, 1)[1] == 1.0


@pytest.mark.slow
def test_a_libero_pro_scene_runs_as_its_base_suite_does(tmp_path):
    """A LIBERO-PRO suite is a scene like libero_object (sim/libero_pro.py): its base suite's horizon, the clean shape
    expert (the libero_object studies' teacher) solving the swapped task 0 from init state 0 (measured: 108 steps)."""
    unit = Unit("shape_clean", "phys_el", PhysVLAConfig.paper(mode="phys_el").to_dict(), task_id=0, first_seed=0,
                episodes=1, expert={"teacher": "shape"}, scene="libero_object_swap")
    assert unit.key == "shape_clean__phys_el__libero_object_swap_t0__s0-0"
    (rec,), _ = run_units([unit], tmp_path, workers=1)
    assert rec["scene"] == "libero_object_swap" and rec["success"] and rec["steps"] < 280
    assert sum(rec["passthrough"].values()) == 0


def _strip_timing(records):
    return [{k: v for k, v in r.items() if k != "t_us_p50"} for r in records]


@pytest.mark.slow
def test_other_scenes_and_the_ray_backend_give_the_same_records(tmp_path):
    """Fetch units (4-D layout) through a one-CPU local Ray instance equal the process pool's."""
    import ray

    cfg = PhysVLAConfig.paper(mode="phys_el", layout="fetch_4d", weighting="task_space").to_dict()
    units = [Unit("sigma=0.20", "phys_el", cfg, 0, 7 + 2 * k, 2, {"action_noise": 0.2, "noise_stage": "grasp"},
                  scene="fetch_pick_place") for k in range(2)]
    assert units[0].key == "sigma=0.20__phys_el__fetch_pick_place__s7-8"
    local, _ = run_units(units, tmp_path / "process", workers=1)
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False)
    try:
        remote, _ = run_units(units, tmp_path / "ray", workers=1, backend="ray")
    finally:
        ray.shutdown()
    assert [r["seed"] for r in local] == [7, 8, 9, 10]
    assert _strip_timing(remote) == _strip_timing(local)
    assert all(r["scene"] == "fetch_pick_place" and sum(r["passthrough"].values()) == 0 for r in local)
    assert len({r["mean_jerk"] for r in local}) == 4  # different seeds, different episodes


def test_unknown_backend_is_a_clear_error(tmp_path):
    import pytest

    with pytest.raises(ValueError, match="unknown backend 'dask'"):
        run_units([], tmp_path, backend="dask")


def test_a_cached_unit_is_keyed_by_its_configuration_and_refused_with_another_expert(tmp_path):
    """eval/run.py names a unit by its configuration's hash: another configuration is another unit (the
    low-pass's parameters count only while it is on); a unit cached under a backbone name whose faults
    changed since is refused, not mixed in."""
    from harness import _check_stale
    from store import config_hash

    from lerobot_physvla.core.config import PRESETS

    def unit(cfg, expert=None):
        return Unit("expert_jitter", config_hash(cfg.to_dict()), cfg.to_dict(), expert=expert or {"action_noise": 0.3})

    on8 = PRESETS["default"].replace(lowpass="adaptive", lowpass_alpha_max=0.8)
    assert unit(on8).key != unit(on8.replace(lowpass_alpha_max=0.6)).key
    assert unit(PRESETS["default"]).key == unit(PRESETS["default"].replace(lowpass_alpha_max=0.8)).key  # off
    old = unit(on8)
    (tmp_path / "units").mkdir()
    (tmp_path / "units" / f"{old.key}.json").write_text(json.dumps({"unit": {"config": old.config,
                                                                             "expert": old.expert}}))
    _check_stale([old], tmp_path)  # the same unit: reused
    with pytest.raises(SystemExit, match="another expert"):
        _check_stale([unit(on8, expert={"action_noise": 0.2})], tmp_path)


def test_a_unit_on_disk_run_with_other_weights_is_not_reused(tmp_path):
    """A learned backbone retrained under the same name: its old units are refused, not mixed in."""
    from harness import _check_stale, policy_fingerprint

    ckpt = tmp_path / "ckpt"
    ckpt.mkdir()
    (ckpt / "model.safetensors").write_bytes(b"weights v1")
    unit = Unit("act_chunk", "baseline", PhysVLAConfig.paper(mode="baseline").to_dict(), policy=str(ckpt))
    (tmp_path / "units").mkdir()
    (tmp_path / "units" / f"{unit.key}.json").write_text(json.dumps(
        {"unit": {"config": unit.config, "expert": {}}, "policy_sha256": policy_fingerprint(ckpt)}))
    _check_stale([unit], tmp_path)  # same weights: reused
    (ckpt / "model.safetensors").write_bytes(b"weights v2")  # retrained
    with pytest.raises(SystemExit, match="other weights"):
        _check_stale([unit], tmp_path)


def test_a_draw_offset_gives_fresh_failure_draws_on_the_same_init_states():
    from types import SimpleNamespace

    from backbones import ExpertBackbone

    from lerobot_physvla.core.config import LIBERO_OSC_POSE

    scene = SimpleNamespace(layout=LIBERO_OSC_POSE, expert={})
    failure = {"aim_noise_m": 0.015, "place_bias_m": 0.05}

    def draws(failure: dict, seed: int) -> tuple:
        bb = ExpertBackbone(scene, failure)
        bb.reset(seed)
        return tuple(bb.expert.aim) + tuple(bb.expert.place_bias)

    assert draws(failure, 3) == draws({**failure, "draw_offset": 0}, 3)  # the default: today's draws
    assert draws({**failure, "draw_offset": 1000}, 3) == draws(failure, 1003)
    assert draws({**failure, "draw_offset": 1000}, 3) != draws(failure, 3)


def test_a_chunked_policy_gets_the_chunk_caps_and_every_other_backbone_the_caps(monkeypatch):
    """Candidate 11 is candidate 10 for every backbone that does not execute chunks: the harness builds
    each unit's corrector for its policy (PhysVLAConfig.for_policy with the policy's n_action_steps)."""
    import harness
    from lerobot_physvla.core.config import preset

    built = []
    from types import SimpleNamespace

    from lerobot_physvla.core.config import LIBERO_OSC_POSE

    monkeypatch.setattr(harness, "_scene", lambda name: SimpleNamespace(layout=LIBERO_OSC_POSE, expert={}))
    monkeypatch.setattr("lerobot_physvla.core.corrector.Corrector", lambda cfg: built.append(cfg))
    cfg = preset("default", chunk_phase_caps=(1.0, 0.05, 1.0, 1.0))
    ckpts = Path(__file__).resolve().parents[2] / "backbones" / "checkpoints"
    for policy in ("", str(ckpts / "act_single"), str(ckpts / "act_chunk")):
        unit = Unit("expert_clean" if not policy else Path(policy).name, "c", cfg.to_dict(), 0, 0, 0, policy=policy)
        harness.compute_unit(unit)
    expert, single, chunked = built
    assert cfg.caps != (1.0, 0.05, 1.0, 1.0)
    assert expert.caps == single.caps == cfg.caps  # act_single: n_action_steps 1
    assert chunked.caps == (1.0, 0.05, 1.0, 1.0)  # act_chunk executes 10 of its 20-step chunk
    assert chunked.replace(phase_caps=cfg.phase_caps, chunk_phase_caps=cfg.chunk_phase_caps) == cfg


def test_a_metaworld_unit_runs_baseline_and_the_default_and_yields_records():
    """One unit per configuration on metaworld/0 (pick-place), MetaWorld's own scripted policy as the teacher,
    one seed, in this process (compute_unit: what a worker runs)."""
    pytest.importorskip("metaworld")
    import harness

    from lerobot_physvla.core.config import preset

    mw = {"layout": "metaworld", "weighting": "task_space"}  # a study's [scene_overrides] metaworld = {...}
    configs = {"baseline": PhysVLAConfig.paper(mode="baseline", **mw), "default": preset("default", **mw)}
    for name, cfg in configs.items():
        unit = Unit("metaworld_clean", name, cfg.to_dict(), task_id=0, first_seed=0, episodes=1,
                    expert={"teacher": "metaworld"}, scene="metaworld")
        assert unit.scene_name == "metaworld/0" and unit.key == f"metaworld_clean__{name}__metaworld_t0__s0-0"
        payload = harness.compute_unit(unit)
        (rec,) = payload["records"]
        assert (rec["scene"], rec["task_id"], rec["seed"], rec["config"]) == ("metaworld", 0, 0, name)
        assert rec["success"] and rec["first_success_step"] == rec["steps"] < 500  # stops on MetaWorld's success
        assert sum(rec["passthrough"].values()) == 0 and 0 < rec["efficiency"] <= 1
        assert payload["unit"]["scene"] == "metaworld"
