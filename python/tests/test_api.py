"""Every public name has a docstring and a stub entry (names and members alike)."""

import ast
from pathlib import Path

import segloc

STUB = Path(segloc.__file__).with_name("__init__.pyi")


def stub_entries():
    tree = ast.parse(STUB.read_text())
    names, members = set(), {}
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        if isinstance(node, ast.ClassDef):
            members[node.name] = {n.name for n in node.body if isinstance(n, ast.FunctionDef)}
    return names, members


def public_members(cls):
    return {n for n in vars(cls) if not n.startswith("_")}


def test_version():
    assert segloc.__version__.count(".") == 2


def test_every_public_name_has_a_docstring_and_a_stub():
    names, members = stub_entries()
    assert STUB.with_name("py.typed").is_file()
    for name in segloc.__all__:
        assert name in names, f"{name} has no stub entry"
        if name == "__version__":
            continue
        obj = getattr(segloc, name)
        assert (obj.__doc__ or "").strip(), f"{name} has no docstring"
        if isinstance(obj, type) and not issubclass(obj, Exception):
            for member in public_members(obj):
                assert member in members[name], f"{name}.{member} has no stub entry"
                doc = getattr(obj, member).__doc__
                assert (doc or "").strip(), f"{name}.{member} has no docstring"
            assert not members[name] - public_members(obj) - {"__init__", "__len__"}, \
                f"{name}: the stub lists members the module lacks"
    assert names <= set(segloc.__all__), f"stub entries the module lacks: {names - set(segloc.__all__)}"
