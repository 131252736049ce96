"""The obstacle's centre x in coefficients files (pipeline.offline.coefficients): absent from the
scene block when 0 (a file of the paper's scene keeps its bytes), written and read back otherwise."""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from pipeline.exceptions import DataFileError
from pipeline.io.jsonio import dumps
from pipeline.model.scene import Scene
from pipeline.offline.coefficients import (
    coefficients_from_json,
    paper_data_path,
    read_coefficients,
    save_coefficients,
)


def test_the_papers_file_is_written_back_byte_for_byte(tmp_path: Path) -> None:
    """The shipped Eq. 9 file, read and written again: the same bytes, no centre key."""
    shipped = paper_data_path("paper_eq9_coefficients.json")
    paper = read_coefficients(shipped)
    assert paper.scene.centre_x_m == 0.0
    assert "centre_x_m" not in paper.to_json()["scene"]
    copy = tmp_path / "c.json"
    save_coefficients(paper, copy)
    assert copy.read_bytes() == dumps(json.loads(shipped.read_text(encoding="utf-8"))).encode("utf-8")
    assert dumps(replace(paper, scene=Scene(centre_x_m=0.0)).to_json()) == dumps(paper.to_json())


def test_a_centre_is_written_and_refused_on_reading(tmp_path: Path) -> None:
    """A coefficients file records a non-zero centre, and reading one is refused by name: the
    online generator and the range certificate place the obstacle at x = 0."""
    paper = read_coefficients(paper_data_path("paper_eq9_coefficients.json"))
    moved = replace(paper, scene=Scene(centre_x_m=-0.025))
    document = moved.to_json()
    assert document["scene"]["centre_x_m"] == -0.025
    assert list(document["scene"])[-4:] == ["centre_x_m", "link_lengths_m", "link_radii_m", "elbow"]
    path = tmp_path / "c.json"
    save_coefficients(moved, path)
    with pytest.raises(DataFileError, match=r"centre_x_m = -0\.025"):
        read_coefficients(path)
    with pytest.raises(DataFileError, match="centre_x_m"):
        coefficients_from_json(document, "memory", "")
