"""The package ``rfsw_plan.validation`` re-exports its public API lazily."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import rfsw_plan.validation as validation

MODULES = ("campaign.simulation", "engine.residuals", "engine.diagnosis", "workbench",
           "report.validate")


@pytest.mark.parametrize("name", validation.__all__)
def test_every_exported_name_is_the_submodule_object(name: str) -> None:
    module = importlib.import_module(f"rfsw_plan.validation.{validation._SOURCES[name]}")
    assert getattr(validation, name) is getattr(module, name)


def test_all_lists_each_source_once_and_nothing_else() -> None:
    assert sorted(validation.__all__) == sorted(set(validation.__all__))
    assert set(validation.__all__) == set(validation._SOURCES)
    assert set(validation._SOURCES.values()) == set(MODULES)
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        _ = validation.nope


def test_public_classes_and_functions_of_the_submodules_are_exported() -> None:
    import inspect

    for mod_name in MODULES:
        mod = importlib.import_module(f"rfsw_plan.validation.{mod_name}")
        for name, value in vars(mod).items():
            if (inspect.isclass(value) and value.__module__ == mod.__name__
                    and not name.startswith("_")):
                assert name in validation.__all__, f"{mod_name}.{name} not exported"


def test_import_is_cheap() -> None:
    code = (
        "import sys, rfsw_plan.validation, rfsw_plan.validation.campaign.simulation\n"
        "from rfsw_plan.validation import run_campaign\n"
        "print(sorted(m for m in ('matplotlib', 'scipy.stats') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
