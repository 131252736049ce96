"""Machine code compiled ahead of time (pipeline.native): a module compiled here from the
package's own source answers as Numba's JIT does, bit for bit, on random queries of the online
core and of the map's lookups; a stale module (its source edited after it was compiled) or a
missing one is not loaded and the JIT answers instead; the modules built with this package, where
they are present, are fresh; bad declarations are refused."""

from __future__ import annotations

import importlib.machinery
import importlib.util
import math
import sys
from pathlib import Path

import numba
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from pipeline import load_coefficients
from pipeline.certify import lookup
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.exceptions import InvalidParameterError
from pipeline.native import Export, NativeModule
from pipeline.online import kernel
from pipeline.online.query_state import state_of

X_RANGE = (-0.03, 0.03)


@numba.njit(cache=False)
def _twice(value: float) -> float:
    return 2.0 * value


def _compiled(native: NativeModule, folder: Path):
    """``native`` compiled into ``folder`` and imported from there, under its own name but not
    registered in ``sys.modules``."""
    native.compiler(str(folder)).compile()
    basename = native.name.rpartition(".")[2]
    (path,) = folder.glob(f"{basename}.*")
    loader = importlib.machinery.ExtensionFileLoader(native.name, str(path))
    module = importlib.util.module_from_spec(importlib.util.spec_from_file_location(native.name, path, loader=loader))
    loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def ahead(tmp_path_factory):
    """The kernel's and the lookup's modules compiled here: (kernel module, lookup module)."""
    return tuple(_compiled(native, tmp_path_factory.mktemp("native")) for native in (kernel.NATIVE, lookup.NATIVE))


@pytest.fixture(scope="module")
def paper():
    return load_coefficients("paper")


@pytest.fixture(scope="module")
def small_map(paper):
    return certify_range(paper, RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8))


def _bits(values) -> np.ndarray:
    flat = [float(u) for v in values for u in (v if isinstance(v, tuple) else (v,))]
    return np.array(flat).view(np.int64)


def _jit(export: Export):
    return export.dispatcher.compile(export.signature)


@settings(max_examples=150, deadline=None)
@given(st.floats(0.0, 0.6), st.floats(0.0, 0.25), st.floats(*X_RANGE), st.floats(0.3, 0.7))
def test_the_core_ahead_of_time_is_the_jits_bit_for_bit(ahead, paper, over_x, small_map, L, W, x, d) -> None:
    """Every value of the core's answer, over (L, W) with and without a map and over (L, W, x),
    including points outside the fitted box and NaN answers."""
    (jit,) = (_jit(e) for e in kernel.NATIVE.exports)
    paper_x = over_x(paper, X_RANGE, seed=3, scale=0.05)
    for coefficients, tables in (
        (paper, small_map.lookup_tables),
        (paper, lookup.NO_TABLES),
        (paper_x, lookup.NO_TABLES),
    ):
        plan = state_of(coefficients).plan
        beyond = (x, math.nan) if plan.extra else (math.nan, math.nan)
        arguments = (L, W, x, d, d if plan.y1_is_top else plan.y1, *beyond, *plan.core, *tables)
        np.testing.assert_array_equal(_bits(ahead[0].query_core(*arguments)), _bits(jit(*arguments)))


def test_the_lookups_ahead_of_time_are_the_jits(ahead, small_map) -> None:
    tables = small_map.lookup_tables
    rng = np.random.default_rng(5)
    points = np.zeros((2000, 4))
    points[:, 0] = rng.uniform(0.05, 0.45, 2000)  # beyond the fitted box on both sides
    points[:, 1] = rng.uniform(0.0, 0.2, 2000)
    jit = {e.name: _jit(e) for e in lookup.NATIVE.exports}
    leaves = ahead[1].leaves_of(*tables, 2, points)
    np.testing.assert_array_equal(leaves, jit["leaves_of"](*tables, 2, points))
    assert (leaves >= 0).any() and (leaves < 0).any()
    for row, leaf in zip(points[:200], leaves[:200], strict=True):
        assert ahead[1].leaf_of(*tables, 2, *row) == jit["leaf_of"](*tables, 2, *row) == leaf
        if leaf >= 0:
            assert ahead[1].bounds_of(tables.bounds, 2, leaf) == jit["bounds_of"](tables.bounds, 2, leaf)


def test_a_stale_module_is_not_loaded_and_the_jit_answers(tmp_path: Path, monkeypatch) -> None:
    source = tmp_path / "source.py"
    source.write_text("the bytes the module is compiled from\n")
    native = NativeModule("native_probe.twice_native", (Export("twice", _twice, "float64(float64)"),), (str(source),))
    (tmp_path / "native_probe").mkdir()
    (tmp_path / "native_probe" / "__init__.py").write_text("")
    native.compiler(str(tmp_path / "native_probe")).compile()
    monkeypatch.syspath_prepend(str(tmp_path))
    loaded = native.load()
    assert loaded.ahead_of_time and type(loaded["twice"]).__name__ == "builtin_function_or_method"
    assert loaded["twice"](1.25) == 2.5
    source.write_text("the bytes the module is compiled from, edited\n")
    stale = native.load()
    assert not stale.ahead_of_time and stale["twice"](1.25) == 2.5
    for name in ("native_probe.twice_native", "native_probe"):
        sys.modules.pop(name, None)


def test_unreadable_sources_do_not_vouch_for_a_module(tmp_path: Path) -> None:
    (export,) = kernel.NATIVE.exports
    unreadable = NativeModule(kernel.NATIVE.name, (export,), (str(tmp_path / "missing.py"),))
    assert not unreadable.load().ahead_of_time


def test_without_its_module_the_jit_answers(small_map) -> None:
    (export,) = (e for e in lookup.NATIVE.exports if e.name == "leaf_of")
    missing = NativeModule("pipeline.certify.no_such_native", (export,), (lookup.__file__,))
    loaded = missing.load()
    assert not loaded.ahead_of_time
    tables = small_map.lookup_tables
    assert loaded["leaf_of"](*tables, 2, 0.25, 0.1, 0.0, 0.0) == lookup.COMPILED["leaf_of"](
        *tables, 2, 0.25, 0.1, 0.0, 0.0
    )


@pytest.mark.parametrize("native", [kernel.NATIVE, lookup.NATIVE], ids=lambda n: n.name)
def test_a_module_built_with_the_package_is_fresh(native: NativeModule) -> None:
    """Where the package was built with its modules (a wheel, an editable install), they were
    compiled from the sources it runs with (after an edit: ``pip install -e .`` rebuilds them)."""
    if importlib.util.find_spec(native.name) is not None:
        assert native.load().ahead_of_time, f"{native.name} is stale: rebuild it (pip install -e .)"


def test_the_digest_is_of_the_source_bytes_in_order(tmp_path: Path) -> None:
    a, b = tmp_path / "a.py", tmp_path / "b.py"
    a.write_text("x = 1\n")
    b.write_text("y = 2\n")
    export = Export("twice", _twice, "float64(float64)")
    digest = NativeModule("p.m_native", (export,), (str(a), str(b))).source_digest()
    assert 0 <= digest < 2**56
    assert NativeModule("p.m_native", (export,), (str(b), str(a))).source_digest() != digest
    b.write_text("y = 3\n")
    assert NativeModule("p.m_native", (export,), (str(a), str(b))).source_digest() != digest


@pytest.mark.parametrize(
    "make",
    [
        lambda e: Export("not an identifier", _twice, "float64(float64)"),
        lambda e: Export("source_digest", _twice, "float64(float64)"),
        lambda e: NativeModule("nodots", (e,), ("a.py",)),
        lambda e: NativeModule("p.m_native", (), ("a.py",)),
        lambda e: NativeModule("p.m_native", (e, e), ("a.py",)),
        lambda e: NativeModule("p.m_native", (e,), ()),
        lambda e: NativeModule("elsewhere.m_native", (e,), ("a.py",)).extension(),
    ],
)
def test_bad_declarations_are_refused(make) -> None:
    with pytest.raises(InvalidParameterError):
        make(Export("twice", _twice, "float64(float64)"))
