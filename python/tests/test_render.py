"""The plan's 3D pictures (baffle.render: VTK offscreen) and its report.html as a browser
shows it (headless Chromium), on the synthetic heart's plan as scripts/sample.sh runs it:
`baffle phantom --heart`, then `baffle plan` from those segment surfaces (prepare, design,
extend, centerline, 1.25 mm mesh, steady CFD)."""

import json
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from conftest import REPO

pytest.importorskip("vtkmodules.vtkIOImage")
from baffle import render  # noqa: E402  (needs vtk)

CI = os.environ.get("CI", "").lower() in ("true", "1")
CHROMIUM_FLAGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--hide-scrollbars",
]


def unavailable(what):
    """Skip without `what`; under CI=true, where .ci/run installs it, fail instead."""
    if CI:
        pytest.fail(f"{what} (CI=true: .ci/run installs it)")
    pytest.skip(what)


def baffle_executable() -> Path:
    path = Path(os.environ.get("BAFFLE_EXECUTABLE") or REPO / "target" / "release" / "baffle")
    if not path.is_file():
        unavailable(f"no baffle executable at {path} (cargo build --release -p baffle-cli, or set BAFFLE_EXECUTABLE)")
    return path


def run(command, **kwargs):
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, command))}\n{result.stdout}\n{result.stderr}"
    return result


@pytest.fixture(scope="module")
def plan(tmp_path_factory):
    """The synthetic heart's plan folder, made once for this module's tests."""
    exe = baffle_executable()
    root = tmp_path_factory.mktemp("heart-plan")
    run([exe, "phantom", "--heart", "--out", root / "heart"])
    result = run(
        [exe, "plan", "--segmentations", root / "heart", "--points", root / "heart" / "suture_points.mrk.json",
         "--bsa", "0.2", "--bp", "107/78", "--steady", "--edge-length-mm", "1.25", "--single-mesh", "--out", root / "plan"],
        cwd=root,
    )
    assert "no 3D pictures" not in result.stdout, result.stdout
    return root / "plan"


def read_png(path: Path) -> np.ndarray:
    from vtkmodules.util.numpy_support import vtk_to_numpy
    from vtkmodules.vtkIOImage import vtkPNGReader

    reader = vtkPNGReader()
    reader.SetFileName(str(path))
    reader.Update()
    image = reader.GetOutput()
    width, height, _ = image.GetDimensions()
    assert width > 0 and height > 0, f"{path}: not a readable PNG"
    # VTK's rows run bottom to top: flipped, row 0 is the top of the picture.
    return vtk_to_numpy(image.GetPointData().GetScalars()).reshape(height, width, -1)[::-1, :, :3].astype(float)


def drawn_fraction(pixels: np.ndarray) -> float:
    """Share of the pixels that are not the white background."""
    return float(np.mean(np.any(pixels < 245, axis=-1)))


def colourful_fraction(pixels: np.ndarray) -> float:
    """Share of strongly coloured pixels (a colour map, the baffle), not greys or text."""
    return float(np.mean(pixels.max(axis=-1) - pixels.min(axis=-1) > 80))


def test_the_plan_embeds_six_distinct_non_blank_pictures(plan):
    report = json.loads((plan / "report.json").read_text())
    assert report["pictures"]["rendered"] is True, report["pictures"]
    manifest = json.loads((plan / "pictures" / "pictures.json").read_text())
    files = [p["file"] for p in manifest["pictures"]]
    assert files == ["context_anterior.png", "context_left_lateral.png", "aortic_cap_face_on.png",
                     "speed_cut_anterior.png", "speed_cut_face_on.png", "pressure_centerline.png"]
    images = {f: read_png(plan / "pictures" / f) for f in files}
    for name, pixels in images.items():
        assert pixels.shape == (600, 800, 3), (name, pixels.shape)
        assert drawn_fraction(pixels) > 0.05, f"{name}: {drawn_fraction(pixels):.1%} drawn"
        assert pixels.std() > 10, f"{name}: flat picture"
        assert colourful_fraction(pixels) > 0.005, f"{name}: no coloured part ({colourful_fraction(pixels):.2%})"
    # Every view shows something else: no two pictures alike.
    for i, a in enumerate(files):
        for b in files[i + 1:]:
            difference = np.abs(images[a] - images[b]).mean()
            assert difference > 3, f"{a} and {b} differ by {difference:.2f} grey levels on average"
    # The colour maps: the speed cut spans blue to red, and so does its colour bar.
    cut = images["speed_cut_face_on.png"]
    red = np.mean((cut[..., 0] > 180) & (cut[..., 1] < 90) & (cut[..., 2] < 90))
    blue = np.mean((cut[..., 2] > 150) & (cut[..., 0] < 90))
    assert red > 0.001 and blue > 0.001, f"red {red:.3%}, blue {blue:.3%}"
    html = (plan / "report.html").read_text()
    assert html.count("data:image/png;base64,") == len(files)


def test_views_are_named_from_the_frame():
    lps = {key: (look, right, up) for key, _, look, right, up in render.anatomical_views(ras=False)}
    ras = {key: (look, right, up) for key, _, look, right, up in render.anatomical_views(ras=True)}
    # The anterior view looks posterior: +y in LPS, -y in RAS; the patient's left on the right.
    assert lps["anterior"][0] == (0, 1, 0) and ras["anterior"][0] == (0, -1, 0)
    for views, frame in ((lps, False), (ras, True)):
        look, right, up = views["anterior"]
        assert render.orientation_letter(right, frame) == "L" and render.orientation_letter(up, frame) == "S"
        look, right, up = views["left_lateral"]
        assert render.orientation_letter(right, frame) == "P" and render.orientation_letter(look, frame) == "R"
    assert [render.round_length_mm(x) for x in (0.7, 1.0, 3.4, 19.9, 20.0, 73.0)] == [0.5, 1.0, 2.0, 10.0, 20.0, 50.0]


def test_a_folder_without_a_completed_plan_is_named(tmp_path):
    (tmp_path / "report.json").write_text(json.dumps({"status": "failed", "failed_stage": "mesh-nominal"}))
    assert render.main([str(tmp_path)]) == 2
    (tmp_path / "report.json").unlink()
    with pytest.raises(render.RenderError, match="report.json"):
        render.render_plan(tmp_path)


def chromium() -> str:
    for name in ("chromium", "chromium-browser", "google-chrome"):
        if shutil.which(name):
            return shutil.which(name)
    unavailable("no chromium on PATH (apt-get install chromium)")


def headless(browser, profile, *args):
    return run([browser, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args], timeout=180)


# Appended to a copy of report.html: after load, the page writes what it shows.
PROBE = """<script>window.addEventListener('load', function () {
  var images = Array.prototype.map.call(document.images, function (i) { return [i.naturalWidth, i.naturalHeight, i.complete]; });
  var out = document.createElement('pre'); out.id = 'probe';
  out.textContent = JSON.stringify({images: images, height: document.body.scrollHeight, title: document.title});
  document.body.appendChild(out);
});</script>"""


def test_the_report_loads_in_headless_chromium(plan, tmp_path):
    browser = chromium()
    html = (plan / "report.html").read_text()
    probe_page = tmp_path / "probe.html"
    probe_page.write_text(html.replace("</body>", PROBE + "</body>"))
    dom = headless(browser, tmp_path / "profile-dom", "--virtual-time-budget=10000", "--dump-dom", probe_page.as_uri()).stdout
    start = dom.index('<pre id="probe">') + len('<pre id="probe">')
    seen = json.loads(dom[start:dom.index("</pre>", start)].replace("&quot;", '"'))
    assert seen["title"] == "Baffle plan"
    assert len(seen["images"]) == 6, seen
    for width, height, complete in seen["images"]:
        assert complete and (width, height) == (800, 600), seen["images"]

    # The page as a reader sees it: its first screens hold the verdict, the table and pictures.
    shot = tmp_path / "report.png"
    width, height = 1100, min(int(seen["height"]) + 40, 8000)
    headless(browser, tmp_path / "profile-shot", f"--window-size={width},{height}", f"--screenshot={shot}", (plan / "report.html").as_uri())
    pixels = read_png(shot)
    keep = os.environ.get("BAFFLE_REPORT_SCREENSHOT")
    if keep:
        shutil.copy(shot, keep)
    assert pixels.shape[:2] == (height, width), pixels.shape
    assert drawn_fraction(pixels) > 0.05, f"{drawn_fraction(pixels):.1%} of the page drawn"
    # The verdict's box (green, yellow or red) near the top, the pictures just below it.
    top = pixels[:500]
    boxed = np.mean((top.max(axis=-1) - top.min(axis=-1) > 15) & (top.min(axis=-1) > 180))
    assert boxed > 0.01, f"no coloured verdict box in the first 500 px ({boxed:.2%})"
    first_screens = pixels[:2000]
    assert colourful_fraction(first_screens) > 0.03, f"{colourful_fraction(first_screens):.2%} of the first 2000 px coloured"
