"""The README's quoted outputs come from the commands it shows: each command block (```bash, ```python) that an
output block (```, no language) follows is run as it stands, from the repository root, and every line of the output
block is (part of) a line it printed, with the timings (decimal numbers, integers before "us") and a timed
rollout's tick count left free."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
FENCE = re.compile(r"^```(\w*)\n(.*?)^```\s*$", re.M | re.S)
TIMING = re.compile(r"\d+\.\d+|\d+(?= ?us\b)")
# a rollout runs for --duration seconds of wall clock: how many ticks it made (and so changed) is the machine's
WALL_CLOCK = re.compile(r"\d+(?= ticks on arm)|(?<=target changed on )\d+")


def shown() -> list[tuple[str, str, str]]:
    """(language, command, quoted output) for each command block the README follows with an output block."""
    blocks = [(m.group(1), m.group(2)) for m in FENCE.finditer((ROOT / "README.md").read_text())]
    return [(lang, cmd, out) for (lang, cmd), (nxt, out) in zip(blocks, blocks[1:])
            if lang in ("bash", "python") and nxt == ""]


def _free(line: str) -> str:
    return re.sub(r"\s+", " ", WALL_CLOCK.sub("#", TIMING.sub("#", line))).strip()


def test_the_readme_quotes_an_output_for_each_way_to_use_it():
    cmds = [cmd for _, cmd, _ in shown()]
    assert len(cmds) == 4, cmds
    for needle in ("lerobot-eval", "lerobot-rollout", "lerobot-physvla-replay", "Corrector("):
        assert sum(needle in c for c in cmds) == 1, needle
    assert _free("p50 14.0 us, 297 us, in 0.19 s, 98 frames, 8%") == "p50 # us, # us, in # s, 98 frames, 8%"


@pytest.mark.slow
@pytest.mark.parametrize("lang, cmd, quoted", shown(), ids=lambda x: x.split()[0][:30] if isinstance(x, str) else "")
def test_each_quoted_output_is_what_its_command_prints(lang, cmd, quoted, tmp_path):
    """Run where a newcomer runs it, the repository root (linked entry by entry into a fresh folder, so that the
    command's outputs/ starts empty as on a fresh clone)."""
    for entry in ROOT.iterdir():
        if entry.name not in ("outputs", ".git"):
            (tmp_path / entry.name).symlink_to(entry)
    argv = [sys.executable, "-c", cmd] if lang == "python" else ["bash", "-euo", "pipefail", "-c", cmd]
    run = subprocess.run(argv, cwd=tmp_path, capture_output=True, text=True, timeout=900,
                         env={**__import__("os").environ, "PYTHONWARNINGS": "ignore"})
    assert run.returncode == 0, run.stderr[-3000:]
    printed = [_free(ln) for ln in (run.stdout + "\n" + run.stderr).splitlines()]
    missing = [ln for ln in quoted.splitlines() if ln.strip() and not any(_free(ln) in p for p in printed)]
    assert not missing, f"quoted but not printed: {missing}\n--- printed:\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}"


def test_the_intro_s_timings_are_those_of_the_quoted_outputs():
    """The introduction's time per step, path by path, is what the quoted outputs below it print (rounded to the
    microsecond): lerobot-eval's corrector p50 per env-step, one Python call, lerobot-rollout's p50 per tick."""
    intro = (ROOT / "README.md").read_text().split("\n## ")[0]
    outs = "\n".join(out for _, _, out in shown())
    quoted = {"lerobot-eval": re.search(r"per env-step: p50 (\d+(?:\.\d+)?) us", outs),
              "one Python call": re.search(r"last call (\d+(?:\.\d+)?) us", outs),
              "lerobot-rollout": re.search(r"time per tick p50 (\d+(?:\.\d+)?) us", outs)}
    said = {"lerobot-eval": re.search(r"(\d+) us p50 \(`lerobot-eval`\)", intro),
            "one Python call": re.search(r"(\d+) us \(one Python call\)", intro),
            "lerobot-rollout": re.search(r"(\d+) us p50 [^(]*\(`lerobot-rollout`\)", intro)}
    for path in quoted:
        assert quoted[path] and said[path], path
        assert int(said[path].group(1)) == round(float(quoted[path].group(1))), path
