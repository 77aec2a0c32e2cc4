"""numpydoc sections on the calibration classes' public methods (issue 40).

Every public method of :class:`~optcal.families.caltypes.base.Calibration` (the interface each
calibration type implements, and whose docstrings an override without its own inherits) that
takes an argument has a ``Parameters`` section, and one that returns something has a
``Returns`` section.  Read from the source with :mod:`ast`, so a missing section fails.  The
same holds for the public methods of every calibration type (lumped, six-position, extended,
peer), an override without a docstring of its own read with the one it inherits
(:func:`inspect.getdoc`).
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


def _type_methods() -> list[tuple[type, str]]:
    from optcal.families.caltypes.extended import ExtendedCalibration
    from optcal.families.caltypes.lumped import LumpedCalibration
    from optcal.families.caltypes.peer import PeerCalibration
    from optcal.families.caltypes.sixpos import SixPositionCalibration

    return [(cls, name) for cls in (LumpedCalibration, SixPositionCalibration, ExtendedCalibration, PeerCalibration)
            for name, value in vars(cls).items()
            if not name.startswith("_") and (isinstance(value, classmethod) or inspect.isfunction(value))]


@pytest.mark.parametrize(("cls", "name"), _type_methods(), ids=[f"{c.__name__}.{n}" for c, n in _type_methods()])
def test_calibration_type_methods_have_their_numpydoc_sections(cls: type, name: str) -> None:
    method = getattr(cls, name)
    doc = inspect.getdoc(method) or ""  # an override without a docstring inherits Calibration's
    signature = inspect.signature(method)
    arguments = [p for p in signature.parameters if p not in ("self", "cls")]
    if arguments:
        assert "Parameters\n----------" in doc, f"{cls.__name__}.{name} takes {arguments}: no Parameters section"
    if signature.return_annotation not in (None, "None", inspect.Signature.empty):
        assert "Returns\n-------" in doc, f"{cls.__name__}.{name} returns a value: no Returns section"
