"""The viewer draws an obstacle moved by its centre x where it is: the obstacle's node carries the
translation to its centre (x_c, d - W/2, 0) with its mesh in its own frame, the desired path and
P1..P5 are those of the moved obstacle, and ``python -m verify.view --x`` passes x to the
generator (a missing or unexpected ``--x`` is one line, exit 2)."""

from __future__ import annotations

import base64
import re
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import umsgpack
from numpy.testing import assert_allclose

from pipeline.offline.coefficients import Coefficients, read_coefficients, save_coefficients
from pipeline.offline.variables import Variables
from pipeline.online.generator import generate
from verify import view
from verify.viewer.drawing import ViewStyle, obstacle_mesh, obstacle_transform
from verify.viewer.trajectory_view import case_from_generated, trajectory_html

LWX = Variables(("L", "W", "x"))
X_M = 0.02
BASE = "/meshcat/trajectory"


def with_x(coefficients: Coefficients) -> Coefficients:
    """``coefficients`` over (L, W, x), with no x terms: the (L, W) answer moved rigidly by x."""
    parameters = {}
    for name, b in coefficients.parameters.items():
        lifted = np.zeros(LWX.basis_size)
        lifted[[0, 1, 2, 4, 5, 7]] = b  # the (L, W) terms' places in the (L, W, x) basis
        parameters[name] = tuple(float(v) for v in lifted)
    return replace(
        coefficients,
        parameters=parameters,
        fitted_range_m={**coefficients.fitted_range_m, "x": (-0.03, 0.03)},
        variables=LWX,
        source="",
        source_sha256="",
    )


def page_commands(html: str) -> list[dict]:
    """The Meshcat commands inlined in an exported page, decoded."""
    blobs = re.findall(r'fetch\("data:application/octet-binary;base64,([A-Za-z0-9+/=]+)"\)', html)
    return [umsgpack.unpackb(base64.b64decode(blob)) for blob in blobs]


def transform_of(commands: list[dict], path: str) -> np.ndarray:
    """The last 4x4 transform set on ``path`` (Meshcat sends it column-major)."""
    matrices = [c["matrix"] for c in commands if c["type"] == "set_transform" and c["path"] == path]
    assert matrices, f"no transform on {path}"
    return np.asarray(matrices[-1], dtype=float).reshape(4, 4).T


def mesh_vertices(commands: list[dict], path: str) -> np.ndarray:
    """The vertices (n, 3) of the triangle mesh set on ``path``."""
    command = next(c for c in commands if c["type"] == "set_object" and c["path"] == path)
    array = command["object"]["geometries"][0]["data"]["attributes"]["position"]["array"]
    return np.frombuffer(array.data if hasattr(array, "data") else array, dtype=np.float32).reshape(-1, 3)


@pytest.fixture(scope="module")
def coefficients_x() -> Coefficients:
    from pipeline.offline.coefficients import paper_data_path

    return with_x(read_coefficients(paper_data_path("paper_eq9_coefficients.json")))


@pytest.fixture(scope="module")
def pages(coefficients_x: Coefficients, arm) -> dict[float, tuple[list[dict], object]]:
    """The exported page's commands and the answer at x = 0 and at x = X_M."""
    style = ViewStyle.for_pixels(samples=64, fps=10)
    out = {}
    for x in (0.0, X_M):
        answer = generate(coefficients_x, 0.25, 0.10, x=x)
        html, _ = trajectory_html(case_from_generated(answer, arm), style)
        out[x] = (page_commands(html), answer)
    return out


def test_the_obstacles_transform_carries_the_x_offset(pages) -> None:
    commands, answer = pages[X_M]
    obstacle = answer.obstacle
    assert obstacle.centre_x_m == pytest.approx(X_M)
    matrix = transform_of(commands, f"{BASE}/obstacle")
    assert_allclose(matrix[:3, :3], np.eye(3), atol=0)
    assert_allclose(matrix[:3, 3], [X_M, obstacle.top_y_m - obstacle.width_m / 2, 0.0], atol=1e-6)
    assert_allclose(matrix, obstacle_transform(obstacle), atol=1e-6)
    # The same obstacle at x = 0: the translation differs by x alone.
    centred = transform_of(pages[0.0][0], f"{BASE}/obstacle")
    assert_allclose(matrix[:3, 3] - centred[:3, 3], [X_M, 0.0, 0.0], atol=1e-6)


def test_the_mesh_is_in_the_obstacles_own_frame_and_lands_on_its_footprint(pages) -> None:
    commands, answer = pages[X_M]
    obstacle = answer.obstacle
    vertices = mesh_vertices(commands, f"{BASE}/obstacle").astype(float)
    half = [obstacle.length_m / 2, obstacle.width_m / 2, obstacle.height_m / 2]
    assert_allclose(vertices.min(axis=0), np.negative(half), atol=1e-6)
    assert_allclose(vertices.max(axis=0), half, atol=1e-6)
    placed = vertices + transform_of(commands, f"{BASE}/obstacle")[:3, 3]
    corners = obstacle.footprint_corners_m()
    assert_allclose(placed[:, :2].min(axis=0), corners.min(axis=0), atol=1e-6)
    assert_allclose(placed[:, :2].max(axis=0), corners.max(axis=0), atol=1e-6)
    assert_allclose(obstacle_mesh(obstacle, centred=True).vertices, vertices, atol=1e-6)
    # The world-frame mesh is still where the obstacle is.
    assert_allclose(obstacle_mesh(obstacle).vertices[:, :2].min(axis=0), corners.min(axis=0), atol=1e-12)


def test_the_path_and_its_points_are_drawn_moved_with_the_obstacle(pages) -> None:
    moved, answer = pages[X_M]
    centred, _ = pages[0.0]
    points = {name: transform_of(moved, f"{BASE}/constraint_points/{name}")[:3, 3] for name in ("P1", "P3", "P5")}
    assert points["P3"][0] == pytest.approx(X_M, abs=1e-6)  # above the moved obstacle's centre
    for name, point in points.items():
        reference = transform_of(centred, f"{BASE}/constraint_points/{name}")[:3, 3]
        assert_allclose(point - reference, [X_M, 0.0, 0.0], atol=1e-6)
    shift = mesh_vertices(moved, f"{BASE}/desired_path") - mesh_vertices(centred, f"{BASE}/desired_path")
    assert_allclose(shift, np.tile([X_M, 0.0, 0.0], (len(shift), 1)), atol=1e-5)
    assert answer.path.points_m[2][0] == pytest.approx(X_M)


def test_view_cli_takes_x_and_refuses_a_missing_or_unexpected_one(
    coefficients_x: Coefficients, tmp_path: Path, capsys
) -> None:
    path = tmp_path / "coefficients.json"
    save_coefficients(coefficients_x, path)
    html = tmp_path / "view.html"
    common = ["--coefficients", str(path), "--L", "0.25", "--W", "0.10", "--samples", "32", "--fps", "5"]
    assert view.main([*common, "--x", str(X_M), "--html", str(html)]) == 0
    commands = page_commands(html.read_text(encoding="utf-8"))
    assert transform_of(commands, f"{BASE}/obstacle")[0, 3] == pytest.approx(X_M, abs=1e-6)
    capsys.readouterr()
    for argv, named in (
        ([*common, "--html", str(tmp_path / "a.html")], "--x"),
        (
            [
                "--coefficients",
                "paper",
                "--L",
                "0.25",
                "--W",
                "0.10",
                "--x",
                "0.01",
                "--html",
                str(tmp_path / "b.html"),
            ],
            "--x",
        ),
        (["--paper-test1", "--x", "0.01", "--html", str(tmp_path / "c.html")], "--x"),
    ):
        assert view.main(argv) == 2
        err = capsys.readouterr().err
        assert len(err.strip().splitlines()) == 1 and named in err and "Traceback" not in err, err
    assert not (tmp_path / "a.html").exists() and not (tmp_path / "b.html").exists()
