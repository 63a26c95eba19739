"""The corrector's outputs on a large seeded set of cases are, bit for bit, the recorded ones
(tests/fixtures/corrector_golden.py: every preset and mode, option variants, three layouts, every
entry of the corrector, bad readings and non-finite actions): a refactor must not move one."""

import json
import sys
import warnings
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "fixtures"))
import corrector_golden as golden  # noqa: E402


def test_every_case_gives_the_recorded_bits():
    want = json.loads(golden.PATH.read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        got = golden.compute()
    assert len(got) >= 200 and set(got) == set(want)
    assert [k for k in want if got[k] != want[k]] == []


def test_the_cases_exercise_what_they_claim():
    """Phases, pass-throughs and guards all occur, so an unchanged digest means something."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        cfg = golden.PRESETS["default"]
        r = golden.run_case(cfg, "call", 7)
    assert set(r["phase"].ravel().tolist()) >= {0, 1, 2, 3}
    assert {"invalid_state", "nonfinite_action"} <= {k for k, _ in r["passthrough"]}
    assert any(k == "held_nonfinite_action" for k, _ in r["guard"])
