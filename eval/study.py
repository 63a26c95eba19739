"""A study file (TOML) and what it stands for: backbones, configurations, seed blocks, comparisons.

    title = "..."                      # the report's heading
    about = "..."                      # what the episodes are (shown under the heading)
    results = "efficacy"               # eval/results/<results>/ (default: the file's stem)
    data = ["efficacy", "learned"]     # where its episodes live (default: [results]); new ones go to the first
    made_by = ["..."]                  # the commands that ran its episodes (shown at the report's top)
    extends = "other.toml"             # optional: inherit [groups], [backbones], [configs], [blocks] from it

    [groups]                           # names for lists of backbones
    experts = ["expert_clean", "expert_jitter"]

    [backbones]                        # a scripted expert with faults, or a trained LeRobot policy
    expert_jitter = {expert = {action_noise = 0.3, aim_noise_m = 0.015}}
    act_single = {policy = "act_single"}          # a recipe of backbones/train_backbones.py, or a path

    [configs]                          # a preset plus overrides (PhysVLAConfig fields), or plain fields
    baseline = {mode = "baseline"}
    "my rim guide" = {preset = "default", rim_guide_m = 0.05}
    "bias 2 cm, told" = {preset = "default", pose_error_m = "truth", perception = {bias_m = 0.02}}
                                       # perception: faults between the scene and the corrector (PoseFaults
                                       # fields for both poses, or object / target tables); "truth": their bound
    "noise 1 cm, filtered" = {preset = "default", pose_error_m = "truth", pose_noise_m = "truth",
                              perception = {noise_m = 0.01}}   # pose_noise_m "truth": the noise's sigma, and then
                                       # pose_error_m "truth" is the bias alone (the filter answers to the noise)
    "markers" = {preset = "default", pose_error_m = 0.01, pose_source = "markers"}
                                       # the poses from ArUco markers the scene renders (so101_env: the rig of
                                       # sim/marker_scene.py); positions with a bound over pose_error_m refused

    [pinned]                           # fields every configuration takes unless it (or its preset, apart
    centre_guide = false               # from the default) sets them: a default's options as they stood when
                                       # the study ran, so a later default leaves its configurations (and
                                       # their hashes) as they were

    [scene_overrides]                  # fields every configuration takes on one scene
    fetch_pick_place = {layout = "fetch_4d", weighting = "task_space"}

    [blocks]                           # a scene, its tasks, init states / seeds (inclusive), backbones
    fresh = {scene = "libero_spatial", tasks = [0, 9], seeds = [35, 39], backbones = "experts"}

    [[compare]]                        # a candidate against a reference (and baseline) on blocks by role
    name = "rim guide at 5 cm"
    candidate = "my rim guide"
    reference = "default"
    design = ["fresh"]
    confirm = []
    rule = [{metric = "net", against = "reference", min = -1}]   # compare.Check
    outcome = "shipped" | "not shipped" | ""                     # what was decided (recorded, not computed)
    verdicts = {design = true, confirm = false}                  # what its rule gave when it was decided
    decision = "docs/decisions/17-rim-guide.md"

    [[report]]                         # what the README shows, in order (report.py SECTIONS)
    kind = "summary"
    ...

Configurations are hashed (store.config_hash) per scene: the rows on disk carry the hash, the study the name.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass, field
from pathlib import Path

EVAL = Path(__file__).resolve().parent
ROOT = EVAL.parent
STUDIES = EVAL / "studies"
POSE_SOURCES = ("markers",)  # a configuration's pose_source: the poses from the scene's rendered markers
UNTOUCHED = range(40, 50)  # LIBERO init states no study may run (on every suite)
RESULTS = EVAL / "results"
ROLES = ("design", "confirm")


@dataclass(frozen=True)
class Block:
    """A seed block: `scene`, its `tasks` (LIBERO task ids; MetaWorld task indices, sim/metaworld_sim.py TASKS;
    [0] elsewhere), `seeds` (init states / expert seeds) and the backbones that run on it."""

    name: str
    scene: str
    tasks: tuple[int, ...]
    seeds: tuple[int, ...]
    backbones: tuple[str, ...]


@dataclass
class Compare:
    name: str
    candidate: str
    reference: str
    baseline: str = "baseline"
    blocks: dict[str, list[str]] = field(default_factory=dict)  # role -> block names
    rule: list = field(default_factory=list)  # compare.Check
    outcome: str = ""
    verdicts: dict[str, bool] = field(default_factory=dict)
    decision: str = ""
    about: str = ""
    also: list[str] = field(default_factory=list)  # more configurations shown beside it
    competent: str = ""  # why this comparison drops the competent-policy check (compare.COMPETENT); "" = it applies

    @property
    def checks(self) -> list:
        """The rule's checks, then the competent-policy check unless the study drops it."""
        from compare import COMPETENT

        return list(self.rule) + ([] if self.competent else [COMPETENT])


def _span(v) -> tuple[int, ...]:
    """[a, b] (inclusive), a list of ints, or one int."""
    if isinstance(v, int):
        return (v,)
    if isinstance(v, list) and len(v) == 2 and all(isinstance(x, int) for x in v) and v[0] <= v[1]:
        return tuple(range(v[0], v[1] + 1))
    if isinstance(v, dict) and "list" in v:
        return tuple(v["list"])
    raise ValueError(f"study: a span is [first, last] or {{list = [...]}}, not {v!r}")


class Study:
    """A parsed study file."""

    def __init__(self, path: str | Path):
        self.path = Path(path).resolve()
        raw = _load(self.path)
        self.raw = raw
        self.name = self.path.stem
        self.title = raw.get("title", self.name)
        self.about = raw.get("about", "")
        self.made_by = list(raw.get("made_by", []))
        self.results = RESULTS / raw.get("results", self.name)  # README and plots
        # where its episodes live: its own results directory, or others' too (the first takes new episodes)
        self.data = [RESULTS / d for d in raw.get("data", [self.results.name])]
        self.groups = {k: list(v) for k, v in raw.get("groups", {}).items()}
        self.backbones = dict(raw.get("backbones", {}))
        self.config_specs = dict(raw.get("configs", {}))
        self.scene_overrides = dict(raw.get("scene_overrides", {}))
        self.pinned = dict(raw.get("pinned", {}))
        self.blocks = {n: self._block(n, b) for n, b in raw.get("blocks", {}).items()}
        self.compares = [self._compare(c) for c in raw.get("compare", [])]
        self.report = list(raw.get("report", []))
        self._configs: dict[tuple[str, str], dict] = {}

    # ---- resolution
    def expand(self, names) -> list[str]:
        """Backbone names with groups expanded, in order, without repeats."""
        names = [names] if isinstance(names, str) else list(names)
        out = []
        for n in names:
            out += self.groups[n] if n in self.groups else [n]
        unknown = [n for n in out if n not in self.backbones]
        if unknown:
            raise SystemExit(f"study {self.name}: unknown backbone(s) {unknown}; declare them under [backbones]")
        return list(dict.fromkeys(out))

    def _block(self, name: str, b: dict) -> Block:
        block = Block(name, b.get("scene", "libero_spatial"), _span(b.get("tasks", 0)), _span(b["seeds"]),
                      tuple(self.expand(b.get("backbones", []))))
        kept = sorted(s for s in block.seeds if s in UNTOUCHED) if block.scene.startswith("libero_") else []
        if kept:
            raise SystemExit(f"study {self.name}: block {name!r} runs LIBERO init states {kept}; {UNTOUCHED.start}-"
                             f"{UNTOUCHED.stop - 1} of every suite stay untouched by tuning and reporting: choose others "
                             "(`eval/run.py --seeds-used <scene>` lists what each study holds)")
        return block

    def seed_roles(self) -> list[tuple[Block, str]]:
        """Each block with what it is for here: design / confirm (a comparison's), or run (shown, no rule)."""
        roles: dict[str, list[str]] = {}
        for c in self.compares:
            for role, names in c.blocks.items():
                for n in names:
                    roles.setdefault(n, []).append(role)
        return [(b, "/".join(dict.fromkeys(roles.get(n, ["run"])))) for n, b in self.blocks.items()]

    def _compare(self, c: dict) -> Compare:
        from compare import Check

        for k in ("candidate", "reference", *c.get("also", [])):
            if k in c and c[k] not in self.config_specs and k != "also":
                raise SystemExit(f"study {self.name}: compare {c.get('name')!r} names an unknown configuration {c[k]!r}")
        blocks = {role: list(c.get(role, [])) for role in ROLES}
        unknown = [b for bs in blocks.values() for b in bs if b not in self.blocks]
        if unknown:
            raise SystemExit(f"study {self.name}: compare {c.get('name')!r} names unknown block(s) {unknown}")
        return Compare(name=c["name"], candidate=c["candidate"], reference=c.get("reference", c.get("baseline", "baseline")),
                       baseline=c.get("baseline", "baseline"), blocks=blocks,
                       rule=[self._check(Check.from_dict(x)) for x in c.get("rule", [])], outcome=c.get("outcome", ""),
                       verdicts=dict(c.get("verdicts", {})), decision=c.get("decision", ""), about=c.get("about", ""),
                       also=list(c.get("also", [])), competent=str(c.get("competent", "")))

    def _check(self, chk):
        """A rule's check with its backbone groups expanded."""
        import dataclasses

        return dataclasses.replace(chk, backbones=tuple(self.expand(chk.backbones)) if chk.backbones else (),
                                   exclude=tuple(self.expand(chk.exclude)) if chk.exclude else (),
                                   cells=tuple(chk.cells))

    def spec(self, name: str) -> dict:
        """Configuration `name` as its fields are given: its preset first, then [pinned]'s fields, then its own. A
        pinned field stands for the default's value: where the preset sets that field apart from the default, the
        preset's value stays."""
        from lerobot_physvla.core.config import PRESETS

        if name not in self.config_specs:
            raise SystemExit(f"study {self.name}: unknown configuration {name!r}; declare it under [configs]")
        own = dict(self.config_specs[name])
        base = PRESETS.get(own.get("preset") or "default", PRESETS["default"])
        pinned = {k: v for k, v in self.pinned.items()
                  if not hasattr(base, k) or getattr(base, k) == getattr(PRESETS["default"], k)}
        return {**({"preset": own.pop("preset")} if "preset" in own else {}), **pinned, **own}

    def config(self, name: str, scene: str = "libero_spatial") -> dict:
        """The configuration `name` as it runs on `scene` (PhysVLAConfig.to_dict())."""
        key = (name, scene)
        if key not in self._configs:
            from lerobot_physvla.core.config import PhysVLAConfig, preset

            from lerobot_physvla.sources.perception import PerceptionConfig

            spec = {k: tuple(v) if isinstance(v, list) else v for k, v in self.spec(name).items()}
            spec.update(self.scene_overrides.get(scene, {}))
            if isinstance(spec.get("layout"), dict):  # an ActionLayout spelled out (the so101 layout: the env's scale)
                from lerobot_physvla.core.config import ActionLayout

                spec["layout"] = ActionLayout(**{k: tuple(v) if isinstance(v, list) else v
                                                 for k, v in spec["layout"].items()})
            base = spec.pop("preset", None)
            source = spec.pop("pose_source", None)
            if source not in (None, *POSE_SOURCES):
                raise SystemExit(f"study {self.name}: configuration {name!r}: pose_source {source!r}; one of "
                                 f"{', '.join(POSE_SOURCES)} (or none: the simulator's poses)")
            try:
                faults = PerceptionConfig.from_dict(spec.pop("perception", {}))
                noise_told = spec.get("pose_noise_m") == "truth"
                if noise_told:  # told the perception's noise: the pose filter (core/pose_filter.py) answers to it
                    spec["pose_noise_m"] = faults.noise_m
                if spec.get("pose_error_m") == "truth":  # told the perception's error bound (less the noise, if told)
                    spec["pose_error_m"] = faults.bias_m if noise_told else faults.error_bound_m
                cfg = preset(base, **spec) if base else PhysVLAConfig(**spec)
                cfg.validate()
            except (TypeError, ValueError) as e:
                raise SystemExit(f"study {self.name}: configuration {name!r}: {e}") from e
            self._configs[key] = (cfg.to_dict() | ({} if faults.exact else {"perception": faults.to_dict()})
                                  | ({"pose_source": source} if source else {}))
        return self._configs[key]

    def config_hash(self, name: str, scene: str = "libero_spatial") -> str:
        from store import config_hash

        return config_hash(self.config(name, scene))

    def backbone_spec(self, name: str) -> dict:
        return self.backbones[name]

    def policy_path(self, name: str, checkpoints: str = "outputs/train") -> Path:
        """The checkpoint directory of a learned backbone (a train_backbones.py recipe or a path)."""
        spec = self.backbones[name]["policy"]
        p = ROOT / spec
        if p.exists() or "/" in spec:
            return p
        import sys

        sys.path.insert(0, str(ROOT / "backbones"))
        import train_backbones

        return train_backbones.trained_or_committed(spec, checkpoints)

    def all_configs_of(self, compare: Compare) -> list[str]:
        return list(dict.fromkeys([compare.baseline, compare.reference, compare.candidate, *compare.also]))


def _load(path: Path) -> dict:
    """The study file, with what it `extends` merged under it (tables merged key by key)."""
    raw = tomllib.loads(path.read_text())
    if "extends" in raw:
        base = _load((path.parent / raw.pop("extends")).resolve())
        for k in ("groups", "backbones", "configs", "blocks", "scene_overrides", "pinned"):
            raw[k] = {**base.get(k, {}), **raw.get(k, {})}
        for k in ("made_by",):
            raw.setdefault(k, base.get(k, []))
    return raw


def shown(path: Path) -> str:
    """A path as the repository names it (relative to its root), or whole when it lies outside."""
    try:
        return str(Path(path).resolve().relative_to(ROOT))
    except ValueError:
        return str(path)


def find(name_or_path: str) -> Path:
    """A study file by path or by name (eval/studies/<name>.toml)."""
    p = Path(name_or_path)
    if p.exists():
        return p
    q = STUDIES / f"{name_or_path}.toml"
    if q.exists():
        return q
    have = ", ".join(sorted(f.stem for f in STUDIES.glob("*.toml")))
    raise SystemExit(f"eval: no study {name_or_path!r}; pass a path or one of: {have}")
