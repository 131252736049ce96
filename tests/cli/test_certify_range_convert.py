"""``python -m pipeline.certify_range --convert MAP``: a map of the JSON formats rewritten as a
header and a leaf table with every number kept; --convert with a coefficients file, or neither,
is one line and exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from pipeline.certify.map_files import FORMAT_ARRAYS, load_region_map
from pipeline.certify.range_certificate import RangeCertificateConfig, certify_range
from pipeline.certify.region_map import save_region_map_json
from pipeline.commands.certify_range import main
from pipeline.online.loading import load_coefficients


def test_a_json_map_is_converted_keeping_every_number(tmp_path: Path) -> None:
    coefficients = load_coefficients("paper")
    region_map = certify_range(coefficients, RangeCertificateConfig(min_cell=1 / 8, boundary_cell=1 / 4, strip_split=0))
    old = tmp_path / "old.json"
    save_region_map_json(region_map, old)
    new = tmp_path / "new" / "region_map.json"
    new.parent.mkdir()
    assert main(["--convert", str(old), "--output", str(new)]) == 0
    assert json.loads(new.read_text())["format"] == FORMAT_ARRAYS and new.with_suffix(".npy").is_file()
    converted = load_region_map(new)
    for name in ("status", "clearance_bound_m", "endpoint_bound_m"):
        assert np.array_equal(getattr(converted, name), getattr(region_map, name)), name
    for name in ("cut_axis", "cut_level", "children"):
        assert np.array_equal(getattr(converted.subpaving, name), getattr(region_map.subpaving, name)), name
    assert main(["--convert", str(old)]) == 0  # in place
    assert json.loads(old.read_text())["format"] == FORMAT_ARRAYS


@pytest.mark.parametrize("argv", [[], ["paper", "--convert", "map.json"]])
def test_convert_with_coefficients_or_neither_is_one_line_exit_2(argv: list[str], capsys) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "--convert" in err
