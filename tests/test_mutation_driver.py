"""The mutation driver's configuration (mutation/run.py, docs/mutation.md), without running it:
every target and test selection exists, and the operator filter keeps the intended set."""

from __future__ import annotations

import importlib.util
import re

from controller_common import ROOT

_spec = importlib.util.spec_from_file_location("mutation_run", ROOT / "mutation" / "run.py")
run = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(run)  # type: ignore[union-attr]


def test_targets_and_their_tests_exist():
    for module, tests in run.TARGETS.items():
        assert (ROOT / module).is_file(), module
        for arg in tests:
            if arg.startswith("tests/"):
                assert (ROOT / arg.split("::")[0]).is_file(), arg


def _excluded(operator: str) -> bool:
    # as Cosmic Ray's operators filter combines the expressions (cr-filter-operators)
    return re.compile("|".join(f"(:?{e})" for e in run.EXCLUDE)).match(operator) is not None


def test_operator_filter_keeps_the_classic_set():
    kept = ["ReplaceBinaryOperator_Add_Sub", "ReplaceBinaryOperator_Mul_Div",
            "ReplaceComparisonOperator_Lt_LtE", "ReplaceComparisonOperator_Eq_NotEq",
            "ReplaceUnaryOperator_USub_UAdd", "ReplaceUnaryOperator_Delete_Not", "NumberReplacer",
            "AddNot", "ReplaceTrueWithFalse", "ZeroIterationForLoop", "ExceptionReplacer"]
    dropped = ["ReplaceBinaryOperator_Add_Mul", "ReplaceBinaryOperator_Add_LShift",
               "ReplaceComparisonOperator_Lt_Eq", "ReplaceComparisonOperator_Eq_Is",
               "ReplaceUnaryOperator_USub_Invert", "VariableReplacer", "RemoveDecorator"]
    assert [op for op in kept if _excluded("core/" + op)] == []
    assert [op for op in dropped if not _excluded("core/" + op)] == []


def test_config_names_the_module_and_its_tests():
    text = run.config_text("models/axes.py")
    assert "module-path = 'models/axes.py'\n" in text
    assert "tests/test_mutation_models.py tests/test_model.py'\n" in text
    assert "-p no:randomly" in text and f"timeout = {run.TIMEOUT_S}\n" in text


def test_every_target_has_a_row_of_scores_that_adds_up():
    """docs/mutation.md's score table: a row per target module (the last run of each), whose
    share killed is (mutants - survived) / mutants to the printed 0.1 %, over the mutants run
    (pending ones are not counted)."""
    text = (ROOT / "docs" / "mutation.md").read_text(encoding="utf-8")
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if len(cells) == 8 and cells[2].startswith("`") and cells[6].endswith("%"):
            module = cells[2].strip("`")
            assert module not in rows, f"two rows for {module}"
            rows[module] = (int(cells[3]), int(cells[4]), int(cells[5]),
                            float(cells[6].rstrip(" %")))
    assert sorted(rows) == sorted(run.TARGETS)
    for module, (mutants, survived, pending, killed) in rows.items():
        assert killed == round(100.0 * (mutants - survived) / mutants, 1), module
        assert 0 <= survived <= mutants and pending >= 0, module
