"""Results as data: a study's episodes in one compressed JSON-lines file, its configurations in one table.

    eval/results/<study>/episodes.jsonl.gz   one row per episode (sorted), keyed by configuration hash
    eval/results/<study>/configs.json        {"configs": {hash: PhysVLAConfig dict},
                                              "backbones": {name: {"expert": {...}} | {"policy_sha256": ...}}}

A row holds what `harness.run_episode` measured (success, steps, jerk, ...) plus where it ran:
`backbone`, `config` (the configuration's hash), `scene`, `task_id`, `seed`. Names of configurations
live in the study file, never in the rows: a study names each hash it shows, so renaming a
configuration never touches data. Everything is written deterministically (sorted rows and keys,
gzip without a timestamp), so re-writing unchanged data leaves the files byte-identical.
"""

from __future__ import annotations

import gzip
import hashlib
import io
import json
from pathlib import Path

EPISODES, CONFIGS = "episodes.jsonl.gz", "configs.json"
KEY = ("backbone", "config", "scene", "task_id", "seed")  # one episode per key


# fields added after episodes were first stored: left out of the effective configuration at these values
# (what every configuration before them did), so older configurations keep their hashes
NEUTRAL = {"pose_error_m": 0.0, "pose_max_age_steps": 5, "geometry": "fixed", "veto_close_lead_s": 0.0,
           "pose_noise_m": 0.0, "centre_guide": False, "centre_guide_once": False, "release_assist_error_k": 0.0,
           "centre_guide_yield_steps": 0, "centre_guide_trailing": True, "close_meets": False,
           "close_meets_onset": False, "approach_pull_m": 0.0, "centre_guide_straddle": False, "carry_far_m": 0.0,
           "approach_pull_stall_steps": 0, "approach_pull_handback": False,
           "approach_pull_open_handback": False, "approach_pull_heading_u": 0.0,
           "carry_clear_m": 0.0, "centre_guide_clears": False, "veto_hold_to_top": False,
           "lift_assist_needs_close": False}
# fields renamed after episodes were first stored (core/config.py ALIASES): hashed under their first names, and
# the saved form's `version` left out, so a rename or a new version keeps every configuration's hash
HASHED_AS = {"place_tol_m": "redirect_tol_m", "place_gain": "redirect_gain"}
PERCEPTION = "perception"  # a study configuration's perception faults (sources/perception.py), kept beside it
POSE_SOURCE = "pose_source"  # ... and where its poses come from ("markers": the scene's rendered markers)


def effective(config: dict) -> dict:
    """The configuration as it acts: a full PhysVLAConfig dict, with the low-pass's parameters reset when the
    low-pass is off, release_assist_error_k when no pose error is told, centre_guide_straddle and centre_guide_clears
    where the guide is off, and centre_guide_trailing where the guide is off or the layout's step gain is 1 (they
    cannot change an action then; a guide kept off a trailing-target layout is the guide off), the NEUTRAL fields
    left out where neutral, and the perception faults between the scene and the corrector (`perception`) and the
    pose source (`pose_source`) where the study sets any."""
    from lerobot_physvla.core.config import PhysVLAConfig

    config = dict(config)
    faults = config.pop(PERCEPTION, None)
    source = config.pop(POSE_SOURCE, None)
    c = PhysVLAConfig.from_dict(config)
    if c.lowpass == "off":
        c = c.replace(lowpass_alpha_max=0.0, lowpass_rough_lo=0.0, lowpass_rough_hi=1.0, lowpass_phases="",
                      lowpass_space="action", lowpass_speed_hi=0.0, lowpass_rough="ema", lowpass_lag="trail")
    if c.pose_error_told_m == 0.0:  # no pose error told: the release assist's widening by it cannot act
        c = c.replace(release_assist_error_k=0.0)
    if not c.centre_guide:  # centre_guide_straddle and centre_guide_clears only shape the guide's pull
        c = c.replace(centre_guide_straddle=False, centre_guide_clears=False)
    if not c.centre_guide or c.action_layout.step_gain >= 1.0:  # centre_guide_trailing cannot change an action
        c = c.replace(centre_guide_trailing=True)
    elif not c.centre_guide_trailing:  # a trailing-target layout with the guide kept off it: the guide is off
        c = c.replace(centre_guide=False, centre_guide_once=False, centre_guide_yield_steps=0,
                      centre_guide_straddle=False, centre_guide_clears=False, centre_guide_trailing=True)
    d = c.to_dict()
    del d["version"]
    d = {HASHED_AS.get(k, k): v for k, v in d.items()}
    for k, v in NEUTRAL.items():
        if d[k] == v:
            del d[k]
    if faults:
        d[PERCEPTION] = dict(sorted(faults.items()))
    if source:
        d[POSE_SOURCE] = source
    return d


def config_hash(config: dict) -> str:
    """12 hex digits of sha256 over the effective configuration (sorted JSON)."""
    return hashlib.sha256(json.dumps(effective(config), sort_keys=True).encode()).hexdigest()[:12]


def row_key(row: dict) -> tuple:
    return tuple(row[k] for k in KEY)


class Store:
    """One study's results directory: read, add and write episode rows and their configurations."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self._rows: dict[tuple, dict] | None = None
        self._meta: dict | None = None

    # ---- reading
    @property
    def rows(self) -> list[dict]:
        return list(self._load().values())

    def _load(self) -> dict[tuple, dict]:
        if self._rows is None:
            self._rows = {}
            path = self.root / EPISODES
            if path.exists():
                with gzip.open(path, "rt") as f:
                    for line in f:
                        r = json.loads(line)
                        self._rows[row_key(r)] = r
        return self._rows

    @property
    def meta(self) -> dict:
        if self._meta is None:
            path = self.root / CONFIGS
            self._meta = json.loads(path.read_text()) if path.exists() else {"configs": {}, "backbones": {}}
        return self._meta

    def has(self, key: tuple) -> bool:
        return key in self._load()

    # ---- writing
    def add_config(self, config: dict) -> str:
        h = config_hash(config)
        self.meta["configs"].setdefault(h, effective(config))
        return h

    def add_backbone(self, name: str, what: dict) -> None:
        """What a backbone name stands for (its expert faults, or its weights' sha256); a name may not change
        meaning inside one study."""
        was = self.meta["backbones"].setdefault(name, what)
        if was != what:
            raise SystemExit(f"store: backbone {name!r} in {self.root} was {was}, now {what}: give it another name")

    def add(self, rows: list[dict]) -> None:
        have = self._load()
        for r in rows:
            have[row_key(r)] = r

    def write(self) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        rows = sorted(self._load().values(), key=lambda r: tuple(str(v) for v in row_key(r)[:3]) + row_key(r)[3:])
        buf = io.BytesIO()
        with gzip.GzipFile(fileobj=buf, mode="wb", mtime=0, compresslevel=9) as f:
            for r in rows:
                f.write((json.dumps(r, sort_keys=True) + "\n").encode())
        _write_bytes(self.root / EPISODES, buf.getvalue())
        meta = {"configs": dict(sorted(self.meta["configs"].items())),
                "backbones": dict(sorted(self.meta["backbones"].items()))}
        _write_bytes(self.root / CONFIGS, (json.dumps(meta, indent=1, sort_keys=True) + "\n").encode())


def _write_bytes(path: Path, data: bytes) -> None:
    tmp = path.with_suffix(path.suffix + ".tmp")
    tmp.write_bytes(data)
    tmp.replace(path)  # atomic: a killed run never leaves a half-written file
