"""The session's stored plans in a child process (``tests/test_readme_commands.py``'s blocks).

A child started with this folder first on ``PYTHONPATH`` and ``RFSW_TEST_STORED_PLANS`` naming a
folder of ``PROBLEM.plan.pickle`` files (the session's ``planned_result``, conftest) imports this
module at start-up (``site``). When the child imports :mod:`rfsw_plan.planning.api`, its ``plan``
is wrapped: ``plan(problem)`` of a bundled problem as its file has it (by name, or loaded and
unchanged), with the problem's own options and no spacing, model or compilation option, returns
the stored plan; every other call plans. So a documented command (``rfsw-plan plan PROBLEM``,
``rfsw_plan.plan("PROBLEM")``) runs as written, from its parsing to the files it writes and what
it prints, without planning the same problem again in every block. Planning is deterministic:
``tests/test_plan_cache.py`` checks that a stored plan writes a fresh plan's bytes.

Nothing is imported until the child imports the planner (a command that never plans starts as
fast as without it)."""

from __future__ import annotations

import importlib.abc
import importlib.machinery
import os
import pickle
import sys
from typing import Any

_DIR = os.environ.get("RFSW_TEST_STORED_PLANS")


def _wrap(api: Any) -> None:
    real = api.plan

    def plan(problem: Any, options: Any = None, **kw: Any) -> Any:
        from rfsw_plan.process.problem import bundled_problem_names, load_problem

        name = problem if isinstance(problem, str) else getattr(problem, "name", None)
        stored = os.path.join(str(_DIR), f"{name}.plan.pickle")
        if (isinstance(name, str) and not any(v is not None for v in kw.values())
                and name in bundled_problem_names() and os.path.exists(stored)):
            as_is = load_problem(name)  # the bundled problem as its file has it
            if options in (None, as_is.planning) and (
                    problem == name or pickle.dumps(problem) == pickle.dumps(as_is)):
                with open(stored, "rb") as f:
                    return pickle.load(f)
        return real(problem, options, **kw)

    api.plan = plan


class _Finder(importlib.abc.MetaPathFinder):
    """Finds :mod:`rfsw_plan.planning.api` as usual and wraps its ``plan`` once loaded."""

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        if name != "rfsw_plan.planning.api":
            return None
        sys.meta_path.remove(self)
        spec = importlib.machinery.PathFinder.find_spec(name, path)
        if spec is None or spec.loader is None:
            return spec
        loader = spec.loader
        run = loader.exec_module

        def exec_module(module: Any) -> None:
            run(module)
            _wrap(module)

        loader.exec_module = exec_module  # type: ignore[method-assign]
        return spec


if _DIR:
    sys.meta_path.insert(0, _Finder())
