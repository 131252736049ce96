"""The documentation users read: the README's Python blocks run as pasted, the README stays short,
and nothing in the README, ``docs/``, ``pipeline/`` or ``verify/`` reads as a diary (dates of
runs, sessions or issues, paths of a machine)."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from pipeline import load_coefficients
from pipeline.certify.map_files import save_region_map
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import DEFAULT_MAP_NAME
from pipeline.offline.coefficients import paper_data_path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


def python_blocks(text: str) -> list[str]:
    """The ```python blocks of a Markdown text, in order."""
    return re.findall(r"^```python\n(.*?)^```", text, flags=re.S | re.M)


def test_the_readme_is_at_most_250_lines_with_a_two_line_quick_start() -> None:
    text = README.read_text(encoding="utf-8")
    assert len(text.splitlines()) <= 250
    quick = re.search(r"## Quick start.*?```bash\n(.*?)```", text, flags=re.S)
    assert quick is not None
    lines = [line for line in quick.group(1).splitlines() if line.strip()]
    assert len(lines) == 2
    assert "pip install" in lines[0] and "python -m pipeline.build" in lines[0]
    assert "pip install" in lines[1] and "pytest" in lines[1]


def test_every_python_block_of_the_readme_runs_as_pasted(tmp_path: Path) -> None:
    """From a folder holding ``results/`` as a build leaves it (here the paper's Eq. 9 written as a
    coefficients file, with a coarse map of it beside), the README's Python blocks run one after
    the other as one script, the build's example included."""
    blocks = python_blocks(README.read_text(encoding="utf-8"))
    assert len(blocks) >= 2 and all("from pipeline import" in block for block in blocks[:1])
    results = tmp_path / "results"
    results.mkdir()
    shutil.copyfile(paper_data_path("paper_eq9_coefficients.json"), results / "coefficients.json")
    coefficients = load_coefficients(results / "coefficients.json")
    coarse = RangeCertificateConfig(min_cell=1 / 16, boundary_cell=1 / 8, strip_split=0)
    save_region_map(certify_range(coefficients, coarse), results / DEFAULT_MAP_NAME)
    script = tmp_path / "readme_blocks.py"
    script.write_text("\n\n".join(blocks), encoding="utf-8")
    environment = {k: v for k, v in os.environ.items() if k != "PYTHONWARNINGS"}
    done = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=1800, cwd=tmp_path, env=environment
    )
    assert done.returncode == 0, done.stderr[-4000:]
    assert "Traceback" not in done.stderr


#: What reads as a diary: a date, a session or an issue, a path of a machine.
DIARY = re.compile(
    r"\b20\d\d-[01]\d-[0-3]\d\b|(?<!new_)\bsessions?\b|\bissues?\b|/work/|/tmp/|/root/|/home/|\btoday\b",
    flags=re.I,
)


def _documents() -> list[Path]:
    files = [README, *sorted((ROOT / "docs").glob("*.md"))]
    for package in ("pipeline", "verify"):
        files += sorted((ROOT / package).rglob("*.py"))
    return files


@pytest.mark.parametrize("path", _documents(), ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_diary_in_docs_or_code(path: Path) -> None:
    hits = [
        f"{path.relative_to(ROOT)}:{number}: {line.strip()}"
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if DIARY.search(line.replace("start_new_session", ""))
    ]
    assert not hits, "\n".join(hits)
