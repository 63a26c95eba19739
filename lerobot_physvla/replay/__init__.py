"""Dataset replay: what the corrector would have done to a recorded LeRobotDataset.

    columns.py   the columns the project's recorder writes and replay reads
    record.py    record scripted or LeRobot policies in a simulator into a LeRobotDataset
    dataset.py   open a local LeRobotDataset as per-episode numpy arrays (clear errors)
    offline.py   feed each frame's recorded action and state through the corrector
    resim.py     re-execute recorded actions open loop in the simulator, with and without it
    policy.py    a LeRobot policy on the recorded observations, against the recorded actions
    shards.py    episodes sharded over a process pool or Ray, with a progress bar
    write.py     a corrected copy of a dataset (a new LeRobotDataset)

The console script is `lerobot-physvla-replay` (lerobot_physvla.scripts.lerobot_physvla_replay).
"""
