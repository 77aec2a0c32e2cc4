"""numpydoc sections on the calibration classes' public methods (issue 40).

Every public method of :class:`~optcal.families.caltypes.base.Calibration` (the interface each
calibration type implements, and whose docstrings an override without its own inherits) that
takes an argument has a ``Parameters`` section, and one that returns something has a
``Returns`` section.  Read from the source with :mod:`ast`, so a missing section fails.
"""

from __future__ import annotations

import ast
import inspect

import pytest

from optcal.families.caltypes import base

_TREE = ast.parse(inspect.getsource(base))
_CLASS = next(n for n in _TREE.body if isinstance(n, ast.ClassDef) and n.name == "Calibration")
_METHODS = [n for n in _CLASS.body if isinstance(n, ast.FunctionDef) and not n.name.startswith("_")]


def _is_property(fn: ast.FunctionDef) -> bool:
    return any(getattr(d, "id", None) == "property" for d in fn.decorator_list)


@pytest.mark.parametrize("fn", _METHODS, ids=[f.name for f in _METHODS])
def test_public_method_has_its_numpydoc_sections(fn: ast.FunctionDef) -> None:
    doc = ast.get_docstring(fn) or ""
    assert doc, f"Calibration.{fn.name} has no docstring"
    arguments = [a.arg for a in fn.args.args + fn.args.kwonlyargs if a.arg not in ("self", "cls")]
    if arguments:
        assert "Parameters\n----------" in doc, f"Calibration.{fn.name} takes {arguments}: no Parameters section"
    returns = fn.returns is not None and not (isinstance(fn.returns, ast.Constant) and fn.returns.value is None)
    if returns and not _is_property(fn):  # a property is documented as an attribute
        assert "Returns\n-------" in doc, f"Calibration.{fn.name} returns a value: no Returns section"
