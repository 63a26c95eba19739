"""Every adaptation of lerobot internals, in one place, checked against the installed version.

lerobot 0.6.1 has no hook for a third-party post-processing stage in `lerobot-eval`, so this
module (and only this module) reaches into it:
- `wrapped_libero_env_factories`: wraps each LIBERO sub-env factory that
  `lerobot.envs.libero.create_libero_envs` builds (for the `libero_physvla` env type);
- `extra_libero_suites`: lets `create_libero_envs` resolve and build suites beyond hf-libero's
  registry (LIBERO-PRO's, for the `libero_physvla` env type), lerobot's own suites unchanged;
- `vector_env_class`: lerobot's own choice of Sync/AsyncVectorEnv;
- `install_eval_hook`: replaces `lerobot.scripts.lerobot_eval.eval_main` with a version that
  (1) adapts the env config (the caller turns `libero` into `libero_physvla`: state export),
  (2) appends a corrector step to the policy postprocessor that `make_pre_post_processors`
      returns (unless the checkpoint's own postprocessor already has one), and
  (3) hands the step to a callback before each rollout (between rollout batches, outside any
      control tick: the diagnostics recorder compacts the finished batch there), and
  (4) hands the step to a callback after the evaluation (diagnostics beside eval_info.json).
It imports nothing of lerobot_physvla: the caller passes in what it needs, so the env type and
the steps can import this module without a cycle.
"""

from __future__ import annotations

import contextlib
import functools
import logging
from collections.abc import Callable

SUPPORTED_LEROBOT = ("0.6.1",)


class UnsupportedLerobot(RuntimeError):
    pass


def installed_lerobot_version() -> str:
    from importlib.metadata import version

    return version("lerobot")


def check_lerobot_version(found: str | None = None) -> None:
    """Raise UnsupportedLerobot (one line, naming the fix) unless lerobot is a supported version."""
    found = installed_lerobot_version() if found is None else found
    if found not in SUPPORTED_LEROBOT:
        raise UnsupportedLerobot(
            f"lerobot-physvla supports lerobot {', '.join(SUPPORTED_LEROBOT)}, found {found}: "
            f"pip install 'lerobot[libero]=={SUPPORTED_LEROBOT[-1]}'"
        )


def vector_env_class(use_async: bool, n_envs: int):
    from lerobot.envs.configs import _make_vec_env_cls

    return _make_vec_env_cls(use_async, n_envs)


@contextlib.contextmanager
def wrapped_libero_env_factories(wrap: Callable):
    """While active, every LIBERO sub-env factory lerobot builds returns `wrap(original_factory)`.

    The wrapped factories are plain picklable partials, so they work in async worker processes.
    """
    from lerobot.envs import libero as lerobot_libero

    original = lerobot_libero._make_env_fns

    def make_env_fns(**kwargs):
        return [functools.partial(wrap, fn) for fn in original(**kwargs)]

    lerobot_libero._make_env_fns = make_env_fns
    try:
        yield
    finally:
        lerobot_libero._make_env_fns = original


@contextlib.contextmanager
def extra_libero_suites(resolve: Callable[[str], object | None], make_env_fns: Callable[..., list]):
    """While active, `create_libero_envs` takes a suite name `resolve(name)` answers (None: not one of these; lerobot's
    own registry resolves it, as before) and builds that suite's sub-env factories with `make_env_fns(**kwargs)` (the
    keyword arguments of lerobot's `_make_env_fns`); every other suite is lerobot's, untouched. Enter it before
    `wrapped_libero_env_factories`, which then wraps these factories too."""
    from lerobot.envs import libero as lerobot_libero

    original_get, original_fns = lerobot_libero._get_suite, lerobot_libero._make_env_fns
    ours: list[object] = []

    def get_suite(name: str):
        suite = resolve(name)
        if suite is None:
            return original_get(name)
        ours.append(suite)
        return suite

    def env_fns(**kwargs):
        if any(kwargs.get("suite") is s for s in ours):
            return make_env_fns(**kwargs)
        return original_fns(**kwargs)

    lerobot_libero._get_suite, lerobot_libero._make_env_fns = get_suite, env_fns
    try:
        yield
    finally:
        lerobot_libero._get_suite, lerobot_libero._make_env_fns = original_get, original_fns


def install_eval_hook(
    step_type: type,
    make_step: Callable[[int], object],
    on_done: Callable[[object, object], None],
    attach: Callable[[object], object],
    adapt_env: Callable[[object], object],
    before_rollout: Callable[[object], None] | None = None,
) -> None:
    """Replace lerobot-eval's `eval_main` (see module docstring).

    step_type: the corrector step class (a postprocessor holding one keeps it); make_step(n) builds
    one to append for a policy that executes n actions per call (its n_action_steps, else 1);
    attach(step) adapts one the checkpoint already has; adapt_env(env_cfg) returns the env config
    to evaluate; on_done(cfg, step) runs after the evaluation with the parsed
    EvalPipelineConfig; before_rollout(step) runs before each of lerobot-eval's `rollout` calls
    (between rollout batches, never inside a control tick).
    """
    check_lerobot_version()
    from lerobot.configs import parser
    from lerobot.configs.eval import EvalPipelineConfig
    from lerobot.scripts import lerobot_eval

    inner = lerobot_eval.eval_main.__wrapped__  # the function under @parser.wrap()
    original_factory = lerobot_eval.make_pre_post_processors
    original_rollout = lerobot_eval.rollout

    def eval_main(cfg):
        cfg.env = adapt_env(cfg.env)
        holder: dict[str, object] = {}

        def make_pre_post_processors(*args, **kwargs):
            pre, post = original_factory(*args, **kwargs)
            step = next((s for s in post.steps if isinstance(s, step_type)), None)
            if step is None:
                policy_cfg = args[0] if args else kwargs.get("policy_cfg")
                # actions the policy executes open loop per call (ACT / Diffusion: n_action_steps)
                step = make_step(int(getattr(policy_cfg, "n_action_steps", 1) or 1))
                post.steps.append(step)
            else:
                step = attach(step)
            holder["step"] = step
            logging.info("physvla: corrector appended to the policy postprocessor: %s", step.config)
            return pre, post

        def rollout(*args, **kwargs):
            if before_rollout is not None and "step" in holder:
                before_rollout(holder["step"])
            return original_rollout(*args, **kwargs)

        lerobot_eval.make_pre_post_processors = make_pre_post_processors
        lerobot_eval.rollout = rollout
        try:
            return inner(cfg)
        finally:
            lerobot_eval.make_pre_post_processors = original_factory
            lerobot_eval.rollout = original_rollout
            if "step" in holder:
                on_done(cfg, holder["step"])

    eval_main.__annotations__ = {"cfg": EvalPipelineConfig}  # draccus reads the real class
    lerobot_eval.eval_main = parser.wrap()(eval_main)
