"""Screenshots of an exported Meshcat page in headless Chromium.

Flags that render Meshcat's WebGL without a GPU: ``--headless --no-sandbox --disable-gpu
--enable-unsafe-swiftshader`` (``--use-gl=swiftshader`` renders a white page), no network
services, a fresh profile directory, and a virtual-time budget long enough for the page's
animation to finish before the screenshot is taken.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

from pipeline.validation import check_positive, check_positive_int

from .errors import ViewerError

#: Executable names tried, in order, when none is configured.
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")


def find_chromium() -> str | None:
    """Path of a Chromium-family browser on PATH, or None."""
    for name in CHROMIUM_NAMES:
        found = shutil.which(name)
        if found:
            return found
    return None


@dataclass(frozen=True)
class BrowserConfig:
    """How to take the screenshot.

    Attributes:
        executable: Browser to run; None: the first of :data:`CHROMIUM_NAMES` on PATH.
        width_px, height_px: Viewport (and image) size [px].
        virtual_time_budget_ms: Virtual time the page runs before the screenshot [ms].
        webgl: False adds ``--disable-webgl --disable-3d-apis`` (a negative control).
        timeout_s: Longest wall-clock time of one attempt [s].
        attempts: Tries before giving up. Under heavy CPU load, headless Chromium with a
            virtual-time budget occasionally never finishes a page that renders large
            frames continuously (an animation); a hung attempt is killed and retried.
    """

    executable: str | None = None
    width_px: int = 1200
    height_px: int = 800
    virtual_time_budget_ms: int = 5000
    webgl: bool = True
    timeout_s: float = 45.0
    attempts: int = 2

    def __post_init__(self) -> None:
        check_positive_int("width_px", self.width_px, minimum=64)
        check_positive_int("height_px", self.height_px, minimum=64)
        check_positive_int("virtual_time_budget_ms", self.virtual_time_budget_ms)
        check_positive("timeout_s", self.timeout_s)
        check_positive_int("attempts", self.attempts)

    @property
    def aspect(self) -> float:
        """Width / height of the image [-]."""
        return self.width_px / self.height_px


def chromium_command(
    executable: str, html_path: Path, png_path: Path, profile_dir: Path, config: BrowserConfig
) -> list[str]:
    """The headless Chromium command line that writes a screenshot of a local page."""
    command = [
        executable,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--enable-unsafe-swiftshader",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--no-first-run",
        "--no-default-browser-check",
        "--hide-scrollbars",
        "--force-device-scale-factor=1",
        f"--user-data-dir={profile_dir}",
        f"--window-size={config.width_px},{config.height_px}",
        f"--virtual-time-budget={config.virtual_time_budget_ms}",
        f"--screenshot={png_path}",
    ]
    if not config.webgl:
        command += ["--disable-webgl", "--disable-3d-apis"]
    return [*command, html_path.resolve().as_uri()]


def screenshot_html(html_path: str | Path, png_path: str | Path, config: BrowserConfig | None = None) -> Path:
    """Render a local HTML file in headless Chromium and save a PNG screenshot.

    Raises:
        ViewerError: no browser found, it failed or timed out, or wrote no image.
    """
    config = config if config is not None else BrowserConfig()
    executable = config.executable or find_chromium()
    if executable is None:
        raise ViewerError(f"no headless browser found (tried {', '.join(CHROMIUM_NAMES)})")
    html_path, png_path = Path(html_path), Path(png_path).resolve()
    if not html_path.is_file():
        raise ViewerError(f"{html_path}: no such HTML file")
    png_path.parent.mkdir(parents=True, exist_ok=True)
    png_path.unlink(missing_ok=True)
    for _ in range(config.attempts):
        if _run_once(executable, html_path, png_path, config):
            return png_path
    raise ViewerError(f"{executable} did not finish within {config.timeout_s:g} s ({config.attempts} attempt(s))")


def _run_once(executable: str, html_path: Path, png_path: Path, config: BrowserConfig) -> bool:
    """One browser run: True if it wrote the screenshot, False if it hung (and was killed).

    Raises:
        ViewerError: the browser finished without writing the screenshot.
    """
    with tempfile.TemporaryDirectory(prefix="viewer-chromium-") as profile:
        command = chromium_command(executable, html_path, png_path, Path(profile), config)
        # A process group of its own, so that on a timeout the browser and its helpers go together.
        proc = subprocess.Popen(
            command,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        try:
            _, stderr = proc.communicate(timeout=config.timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.communicate()
            png_path.unlink(missing_ok=True)
            return False
    if not png_path.is_file():
        tail = (stderr.strip().splitlines() or ["no output"])[-1]
        raise ViewerError(f"{executable} wrote no screenshot (exit code {proc.returncode}): {tail}")
    return True
