"""The kernels compiled without reference counting allocate nothing, nor does anything they call.

A function compiled with ``evtms._jit.uncounted()`` may not make an array:
numba refuses to compile one that does, and it compiles the functions such a
kernel calls with the kernel's own options. A warm numba cache hides the fault
(a callee cached for a counted caller loads as it is), so this reads the
source instead: from every uncounted kernel, each function it can call,
by name, across the package.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np

import evtms
from evtms._jit import jit, numba_enabled, uncounted

PACKAGE = Path(evtms.__file__).parent
#: NumPy calls that make an array.
ALLOCATING = {
    "array", "empty", "zeros", "ones", "full", "arange", "linspace", "concatenate", "stack",
    "empty_like", "zeros_like", "ones_like", "full_like", "copy", "ascontiguousarray",
}  # fmt: skip


def _uncounted_decorator(dec: ast.expr) -> bool:
    """``@jit(counted=False)`` or ``@...njit(..., **uncounted())``."""
    if not isinstance(dec, ast.Call):
        return False
    if any(k.arg == "counted" and isinstance(k.value, ast.Constant) and k.value.value is False for k in dec.keywords):
        return True
    return any(
        k.arg is None and isinstance(k.value, ast.Call) and getattr(k.value.func, "id", "") == "uncounted"
        for k in dec.keywords
    )


def _modules() -> dict[str, tuple[dict[str, ast.FunctionDef], dict[str, tuple[str, str]]]]:
    """Per module of the package (``evtms.x.y``): its module-level functions by name, and the names
    it imports from the package's modules (``name -> (module, name there)``)."""
    out = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
        module = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        tree = ast.parse(path.read_text(encoding="utf-8"))
        defs = {n.name: n for n in tree.body if isinstance(n, ast.FunctionDef)}
        imports = {
            (alias.asname or alias.name): (node.module, alias.name)
            for node in ast.walk(tree)
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("evtms")
            for alias in node.names
        }
        out[module] = (defs, imports)
    return out


def _resolve(modules, module: str, name: str) -> tuple[str, ast.FunctionDef] | None:
    """The definition ``name`` means in ``module``: its own, or the one it imports (followed through
    re-exports); None for anything else (builtins, math, numba)."""
    for _ in range(5):
        defs, imports = modules.get(module, ({}, {}))
        if name in defs:
            return module, defs[name]
        if name not in imports:
            return None
        module, name = imports[name]
    return None


def _allocations(fn: ast.FunctionDef) -> list[str]:
    """The array-making calls in ``fn``'s body (``np.empty(...)``, ``x.copy()``)."""
    found = []
    for call in (n for n in ast.walk(fn) if isinstance(n, ast.Call) and isinstance(n.func, ast.Attribute)):
        owner = call.func.value
        if call.func.attr in ALLOCATING and (getattr(owner, "id", "") == "np" or call.func.attr == "copy"):
            found.append(f"{ast.unparse(call.func)} (line {call.lineno})")
    return found


def _callees(fn: ast.FunctionDef) -> set[str]:
    """Names ``fn`` calls (``f(...)``)."""
    names = set()
    for call in (n for n in ast.walk(fn) if isinstance(n, ast.Call)):
        if isinstance(call.func, ast.Name):
            names.add(call.func.id)
    return names


def test_every_uncounted_kernel_reaches_no_allocation():
    modules = _modules()
    roots = [
        (module, fn)
        for module, (defs, _) in modules.items()
        for fn in defs.values()
        if any(_uncounted_decorator(d) for d in fn.decorator_list)
    ]
    # The kernels this rests on: the LUT interpolation, the closures' loops, the coil march.
    names = {fn.name for _, fn in roots}
    assert {"interpolate_in", "evaluate_in", "_run_slots", "_solve_each", "march_in", "chiller_in", "wcc_in"} <= names
    faults = []
    for module, root in roots:
        seen, stack = set(), [(module, root, root.name)]
        while stack:
            where, fn, path = stack.pop()
            if (where, fn.name) in seen:
                continue
            seen.add((where, fn.name))
            faults += [f"{module}:{root.name} -> {path}: {a}" for a in _allocations(fn)]
            for name in _callees(fn) - {fn.name}:
                found = _resolve(modules, where, name)
                if found is not None:
                    stack.append((*found, f"{path} -> {found[0]}:{name}"))
    assert not faults, "uncounted kernels that allocate:\n" + "\n".join(sorted(set(faults)))


def test_the_check_sees_an_allocation_through_a_call():
    """The walk above follows calls: an allocation two calls down is found."""
    tree = ast.parse("def a(x):\n    return b(x)\n\ndef b(x):\n    return c(x)\n\ndef c(x):\n    return np.empty(3)\n")
    fns = {fn.name: fn for fn in tree.body}
    assert _callees(fns["a"]) == {"b"} and _allocations(fns["c"]) == ["np.empty (line 8)"]
    assert not _allocations(fns["a"])


def test_an_uncounted_kernel_computes_what_the_counted_one_does():
    """The same function compiled both ways: the same numbers on arrays it is handed."""

    def weighted(a, w, out):
        s = 0.0
        for i in range(a.size):
            out[i] = a[i] * w[i]
            s += out[i]
        return s

    a, w = np.linspace(0.1, 2.0, 17), np.linspace(3.0, -1.0, 17)
    out_c, out_u = np.empty(17), np.empty(17)
    assert jit(weighted)(a, w, out_c) == jit(weighted, counted=False)(a, w, out_u)
    np.testing.assert_array_equal(out_c, out_u)
    if numba_enabled():
        assert uncounted() in ({"_nrt": False}, {})
