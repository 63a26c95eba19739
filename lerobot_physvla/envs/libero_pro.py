"""LIBERO-PRO's perturbed suites under lerobot's LIBERO env, for the `libero_physvla` env type.

    lerobot-eval --env.type=libero_physvla --env.task=libero_object_swap [--env.cameras=false] ...

lerobot's `create_libero_envs` resolves a suite through hf-libero's benchmark registry and loads init states with
torch; LIBERO-PRO's suites (sim/libero_pro.py) are in neither registry, and their init states are .npz files. Inside
`libero_physvla`'s create_envs (compat.extra_libero_suites) a LIBERO-PRO suite name resolves to a `LiberoProSuite`
and each of its sub-envs is a `LiberoProEnv`: lerobot's own `LiberoEnv` with the task's BDDL file, its .npz init
states and its base suite's episode length, LIBERO-PRO's objects registered in whichever process builds it (async
workers included). lerobot's `libero` env type with no physvla flag never sees these suites.
"""

from __future__ import annotations

from functools import partial

from lerobot.envs.libero import LiberoEnv

from lerobot_physvla.sim import libero_pro


class LiberoProSuite:
    """What lerobot's create_libero_envs and LiberoEnv read of a suite: `name`, `tasks` (libero_pro.ProTask, the
    fields of hf-libero's Task), `n_tasks`, `get_task(i)`; every task's objects checked when it is made (an
    unbuildable suite is a LiberoProError here, in the main process, not in a worker)."""

    def __init__(self, name: str):
        self.name = name
        self.tasks = [libero_pro.task(name, i) for i in range(len(libero_pro.tasks(name)))]
        self.n_tasks = len(self.tasks)

    def get_task(self, i: int) -> libero_pro.ProTask:
        return self.tasks[i]


def resolve(name: str) -> LiberoProSuite | None:
    """A LIBERO-PRO suite by name; None for any other name (lerobot's registry resolves it)."""
    return LiberoProSuite(name) if libero_pro.is_pro_suite(name) else None


class LiberoProEnv(LiberoEnv):
    """lerobot's LiberoEnv on a LIBERO-PRO task: init states from the task's .npz (`init_state_id` as lerobot's: the
    episode index, then + n_envs each reset), episode length its base suite's unless given."""

    def __init__(self, task_suite: LiberoProSuite, task_id: int, task_suite_name: str, init_states: bool = True,
                 hard_reset: bool = True, **kwargs):
        if not hard_reset and not init_states:
            raise ValueError("hard_reset=False requires init_states=True")
        libero_pro.register_objects()
        # lerobot's constructor would torch.load the init states from hf-libero's folder: take them from the .npz
        super().__init__(task_suite=task_suite, task_id=task_id, task_suite_name=libero_pro.base_suite(task_suite_name),
                         init_states=False, hard_reset=True, **kwargs)
        self.init_states, self.hard_reset = init_states, hard_reset
        self.task_suite_name = task_suite_name
        self._init_states = libero_pro.init_states(task_suite.get_task(task_id)) if init_states else None


def make_env_fns(*, suite: LiberoProSuite, suite_name: str, task_id: int, n_envs: int, camera_names: list[str],
                 episode_length: int | None, init_states: bool, gym_kwargs: dict, control_mode: str,
                 camera_name_mapping: dict[str, str] | None = None, is_libero_plus: bool = False) -> list:
    """n_envs picklable factories of LiberoProEnv for one task (lerobot's `_make_env_fns`, same arguments)."""
    if is_libero_plus:
        raise ValueError(f"physvla: {suite_name} is a LIBERO-PRO suite, not a LIBERO-plus one: "
                         "drop --env.is_libero_plus")
    return [partial(LiberoProEnv, task_suite=suite, task_id=task_id, task_suite_name=suite_name,
                    camera_name=camera_names, init_states=init_states, episode_length=episode_length,
                    episode_index=episode_index, n_envs=n_envs, control_mode=control_mode,
                    camera_name_mapping=camera_name_mapping, **gym_kwargs)
            for episode_index in range(n_envs)]
