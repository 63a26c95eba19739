"""Episodes sharded over a local process pool or Ray, with a progress bar.

`map_shards(fn, cfg, items)` splits `items` (one per episode) into shards of whole episodes and
calls `fn(cfg, shard, batch=...)` on each, in this process (workers <= 1), in a process pool, or
as Ray tasks (`backend="ray"`: joins $RAY_ADDRESS or starts a local instance); `fn` returns one
result per item. Results come back in no particular order.
"""

from __future__ import annotations

import os

from tqdm import tqdm

BACKENDS = ("process", "ray")


def map_shards(fn, cfg: dict, items: list, workers: int = 1, backend: str = "process", batch: int = 64,
               progress: bool = True, desc: str = "replay") -> list:
    if backend not in BACKENDS:
        raise ValueError(f"physvla: unknown backend {backend!r}; choose one of {', '.join(BACKENDS)}")
    workers = max(1, int(workers))
    size = max(1, min(batch, -(-len(items) // workers)))  # whole episodes; at least one shard per worker
    shards = [items[i:i + size] for i in range(0, len(items), size)]
    out: list = []
    bar = tqdm(total=len(items), desc=desc, unit="episode", disable=not progress)
    try:
        if workers == 1 and backend == "process":
            for s in shards:
                out += fn(cfg, s, batch=batch)
                bar.update(len(s))
        elif backend == "process":
            import multiprocessing as mp
            from concurrent.futures import ProcessPoolExecutor, as_completed

            # spawn: the parent may hold threads (torch, datasets) that fork would copy mid-lock
            with ProcessPoolExecutor(max_workers=min(workers, len(shards)), mp_context=mp.get_context("spawn"),
                                     initializer=_one_thread) as pool:
                futures = {pool.submit(fn, cfg, s, batch=batch): len(s) for s in shards}
                for f in as_completed(futures):
                    out += f.result()
                    bar.update(futures[f])
        else:
            import ray

            if not ray.is_initialized():
                ray.init(address=os.environ.get("RAY_ADDRESS"), num_cpus=None if os.environ.get("RAY_ADDRESS") else workers,
                         include_dashboard=False, log_to_driver=False)
            remote = ray.remote(num_cpus=1)(fn)
            pending = {remote.remote(cfg, s, batch=batch): len(s) for s in shards}
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    out += ray.get(ref)
                    bar.update(pending.pop(ref))
    finally:
        bar.close()
    return out


def _one_thread() -> None:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
