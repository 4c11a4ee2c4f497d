"""Sweeps: a suite's tasks (machine × path × planner × seed × preset × variation) on Dask.

- :mod:`.suite` — the one suite-file parser (``pkmbench run`` and ``sweep`` alike) and the
  task keys; :mod:`.engine` — running tasks (in-process or on a Dask cluster);
  :mod:`.table` — the task table (SQLite), the resume log
  of one sweep folder; :mod:`.to_store` — its finished tasks into the results store; :mod:`.tasks` — the task functions.

The task-function interface is described in :mod:`.engine`.
"""
from harness.sweep.engine import (DEFAULT_TASK, SweepError, SweepResult, execute_task, resolve_task_fn,
                                  run_sweep, tasks_from_suite_file)
from harness.sweep.table import TaskTable, TaskTableError, flatten
from harness.sweep.suite import (SuiteError, code_version, expand, load_suite, make_task, task_key, task_label,
                                 user_fmus_info)

__all__ = ["run_sweep", "SweepResult", "SweepError", "TaskTable", "TaskTableError", "flatten", "expand",
           "load_suite", "make_task", "task_key", "task_label", "code_version", "SuiteError",
           "execute_task", "resolve_task_fn", "DEFAULT_TASK", "tasks_from_suite_file", "user_fmus_info"]
