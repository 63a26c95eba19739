import sys
from pathlib import Path

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
