"""A worker keeps the scenes it builds for reuse, but only the most recent few (a LIBERO scene holds ~0.5 GB: one
worker visiting every task of three suites was killed for memory before the cache had a bound)."""

from types import SimpleNamespace

from lerobot_physvla.sim import scenes


def test_the_cache_reuses_a_scene_and_closes_the_least_recently_used_beyond_its_bound(monkeypatch):
    built, closed = [], []

    def make(name):
        built.append(name)
        return SimpleNamespace(name=name, env=SimpleNamespace(close=lambda: closed.append(name)))

    monkeypatch.setattr(scenes, "make_scene", make)
    cache = scenes.SceneCache(most=2)
    a = cache.get("libero_object/0")
    assert cache.get("libero_object/0") is a and built == ["libero_object/0"]
    cache.get("libero_object/1")
    cache.get("libero_object/0")  # used again: now the most recent
    cache.get("libero_object/2")  # over the bound: the least recently used (task 1) goes, closed
    assert closed == ["libero_object/1"]
    cache.get("libero_object/1")
    assert built == ["libero_object/0", "libero_object/1", "libero_object/2", "libero_object/1"]
    assert closed == ["libero_object/1", "libero_object/0"]
