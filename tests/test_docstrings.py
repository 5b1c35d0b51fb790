"""Public functions outside the estimators have numpydoc Parameters and Returns sections, and annotations
that resolve (tests/test_sklearn_conventions.py checks the estimators' methods)."""

import ast
import importlib
import inspect
import pkgutil
import textwrap
import typing

import pytest

import tghop.cooc

#: The modules held to it: the co-occurrence cGAN's package (every module, those split off later too), the
#: batch manifest, the settings table and the fit options, colour profiles, GPDM and the co-occurrence
#: statistics.
MODULES = sorted({f"tghop.cooc.{m.name}" for m in pkgutil.iter_modules(tghop.cooc.__path__)} | {
    "tghop.cooc", "tghop.manifest", "tghop.settings", "tghop.fit_options", "tghop.profiles", "tghop.gpdm",
    "tghop.cooccurrence"})


def _returns_value(function) -> bool:
    """Whether ``function``'s own body (not a nested function's) returns something other than None or yields."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(function))).body[0]
    stack = list(tree.body)
    while stack:
        node = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
            continue
        if isinstance(node, (ast.Yield, ast.YieldFrom)):
            return True
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            return True
        stack.extend(ast.iter_child_nodes(node))
    return False


def _public_functions(module_name):
    """``(qualified name, function, whether its first parameter is self or cls)`` of the public functions
    defined in the module, and of the public methods (static and class methods too) of its public classes."""
    module = importlib.import_module(module_name)
    for name, obj in vars(module).items():
        if name.startswith("_") or getattr(obj, "__module__", None) != module_name:
            continue
        if inspect.isfunction(obj):
            yield name, obj, False
        elif inspect.isclass(obj):
            for attr, member in vars(obj).items():
                if attr.startswith("_"):
                    continue
                if isinstance(member, staticmethod):
                    yield f"{name}.{attr}", member.__func__, False
                elif isinstance(member, classmethod):
                    yield f"{name}.{attr}", member.__func__, True
                elif inspect.isfunction(member):
                    yield f"{name}.{attr}", member, True


def test_the_checked_modules_hold_public_functions():
    found = {m: [q for q, _, _ in _public_functions(m)] for m in MODULES}
    assert all(found[m] for m in MODULES if m != "tghop.cooc"), found  # the package's face only re-exports
    assert "tghop.cooc.assembly" in MODULES and "tghop.cooc.training" in MODULES


@pytest.mark.parametrize("module_name", MODULES)
def test_every_public_function_has_numpydoc_parameters_and_returns(module_name):
    # 47 functions of these modules (manifest's parsers, the settings table, fit options, profiles, GPDM's
    # pyramid and memory, the cGAN's tiling and networks, ...) had a line or a paragraph: neither section.
    missing = []
    for qualname, function, bound in _public_functions(module_name):
        doc = inspect.getdoc(function) or ""
        takes = list(inspect.signature(function).parameters)[1 if bound else 0:]
        if takes and "\nParameters\n----" not in doc:
            missing.append(f"{qualname}: Parameters")
        if _returns_value(function) and not ("\nReturns\n----" in doc or "\nYields\n----" in doc):
            missing.append(f"{qualname}: Returns")
    assert not missing


def test_the_section_check_sees_a_missing_section():
    def bare(x):
        """One line."""
        return x

    def nested_only(x):
        """Parameters
        ----------
        x : int
        """
        def inner():
            return x

        inner()

    assert _returns_value(bare) and not _returns_value(nested_only)


@pytest.mark.parametrize("module_name", MODULES)
def test_every_public_functions_annotations_resolve(module_name):
    # cooc.training annotated fit's return with the string "CoocGAN", a name that module cannot import:
    # typing.get_type_hints(CoocGAN.fit) raised NameError (and pyflakes reported an undefined name).
    unresolved = []
    for qualname, function, _ in _public_functions(module_name):
        try:
            typing.get_type_hints(function)
        except NameError as exc:
            unresolved.append(f"{qualname}: {exc}")
    assert not unresolved
