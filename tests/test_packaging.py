"""What users install is a wheel: it must hold every file the package reads at run time, and a
program run from an empty folder must find them there (not in a clone)."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def wheel(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A wheel built from this checkout (pip's isolated build, as ``pip install .`` does)."""
    out = tmp_path_factory.mktemp("wheel")
    done = subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "--wheel-dir", str(out), str(ROOT)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    (path,) = out.glob("twolink_obstacle-*.whl")
    return path


def test_the_wheel_holds_every_runtime_file(wheel: Path) -> None:
    names = set(zipfile.ZipFile(wheel).namelist())
    data = sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "pipeline" / "data").iterdir())
    assert data and "pipeline/data/planar_2link.urdf" in data
    missing = [name for name in data if name not in names]
    assert not missing, f"runtime files missing from the wheel: {missing}"
    sources = {
        p.relative_to(ROOT).as_posix() for package in ("pipeline", "verify") for p in (ROOT / package).rglob("*.py")
    }
    assert not sources - names, sorted(sources - names)
    assert not [n for n in names if n.startswith(("tests/", "scripts/", "urdf/"))]
    # The query's machine code, compiled ahead of time (pipeline.native; this machine has a C compiler).
    for module in ("pipeline/online/kernel_native.", "pipeline/certify/lookup_native."):
        assert [n for n in names if n.startswith(module) and n.endswith((".so", ".pyd"))], f"{module}* not in the wheel"


def test_an_installed_wheel_finds_its_files_from_an_empty_folder(wheel: Path, tmp_path: Path) -> None:
    site = tmp_path / "site"
    done = subprocess.run(
        [sys.executable, "-m", "pip", "install", "--no-deps", "--quiet", "--target", str(site), str(wheel)],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    code = (
        "import pipeline, sys\n"
        "from pipeline.model.arm import DEFAULT_URDF\n"
        "from pipeline.offline.coefficients import paper_data_path\n"
        f"assert pipeline.__file__.startswith({str(site)!r}), pipeline.__file__\n"
        "assert DEFAULT_URDF.is_file() and paper_data_path('paper_table2_doe.json').is_file()\n"
        "arm = pipeline.load_planar_arm()\n"
        "answer = pipeline.generate(pipeline.load_coefficients('paper'), 0.27, 0.09)\n"
        "from pipeline.online.kernel import COMPILED\n"
        "print(*(round(v, 9) for v in arm.link_lengths_m), round(answer.duration_s, 3), COMPILED.ahead_of_time)\n"
    )
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    environment["PYTHONPATH"] = str(site)
    done = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=120, cwd=empty, env=environment
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[:2] == ["0.3", "0.35"]
    assert done.stdout.split()[3] == "True"  # the installed core is the wheel's compiled module
