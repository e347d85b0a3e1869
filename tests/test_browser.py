"""replay.html and report.html in a real browser: Debian's chromium driven by Playwright.

The browser is never downloaded: the tests launch /usr/bin/chromium (or $SINGPLAN_CHROMIUM).
Where it or Playwright is missing they skip with the reason, except under CI=true, where
`.ci/run` installs both and the tests must run.
"""

from __future__ import annotations

import os
import shutil
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

from singplan.cli import main
from singplan.outputs.viewer import ANIMATION_STEP_S, robot_of
from singplan.results.trajectory import Trajectory, load

CHROMIUM = os.environ.get("SINGPLAN_CHROMIUM", "/usr/bin/chromium")
# the flags this machine needs (no GPU, no sandbox as root, no background network calls)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--use-gl=swiftshader", "--enable-unsafe-swiftshader"]
SHARED_TASK = Path(__file__).resolve().parents[2] / "shared" / "scenarios" / "kuka_kr6_r900_2__wrist_near_lin.yaml"
EXAMPLE_TASK = Path(__file__).resolve().parents[1] / "examples" / "abb_near_miss_auto.yaml"
pytestmark = pytest.mark.slow  # a real browser


def _missing() -> str | None:
    if not Path(CHROMIUM).is_file():
        return f"no chromium at {CHROMIUM} (Debian package 'chromium'; .ci/run installs it)"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return "Playwright's Python package is not installed (test extra)"
    return None


if (reason := _missing()) is not None:
    if os.environ.get("CI") == "true":
        raise RuntimeError(f"CI=true but the browser tests cannot run: {reason}")
    pytest.skip(reason, allow_module_level=True)

from playwright.sync_api import Browser, Page, sync_playwright  # noqa: E402


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        yield b
        b.close()


@pytest.fixture(scope="module")
def planned(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Output folder of a public wrist near-miss scenario (the bundled example without ../shared)."""
    task = SHARED_TASK if SHARED_TASK.is_file() else EXAMPLE_TASK
    out = tmp_path_factory.mktemp("browser") / "out"
    assert main(["plan", str(task), "-o", str(out), "--quiet"]) == 0
    return out


def _open(browser: Browser, path: Path) -> tuple[Page, list[str]]:
    """Open a page from disk with the network cut off; the list collects page errors and any
    request that tried to leave the disk."""
    page = browser.new_page(viewport={"width": 1200, "height": 800})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("request", lambda r: None if r.url.startswith(("file:", "data:", "blob:")) else errors.append(r.url))
    page.route("**/*", lambda route: route.continue_() if route.request.url.startswith("file:") else route.abort())
    page.goto(path.as_uri())
    return page, errors


def _node_pose(page: Page, path: list[str]) -> list[float]:
    """Position (3) and quaternion xyzw (4) of a scene node's object; fails if the node is absent."""
    return page.evaluate("""(path) => {
        let node = window.singplan.viewer.scene_tree;
        for (const name of path) {
            node = node.children[name];
            if (node === undefined) throw new Error("no scene node " + path.join("/"));
        }
        return [...node.object.position.toArray(), ...node.object.quaternion.toArray()];
    }""", path)


def _models(traj: Trajectory) -> tuple[pin.Model, pin.GeometryModel]:
    """The full URDF model and its visual geometry, as Pinocchio loads them."""
    urdf = robot_of(traj).urdf_path
    model, _, visual = pin.buildModelsFromUrdf(str(urdf), package_dirs=[str(p) for p in urdf.parents])
    return model, visual


def _expected_pose(traj: Trajectory, k: int, geometry: str) -> tuple[np.ndarray, np.ndarray]:
    """Placement of a visual geometry at sample k, from Pinocchio (position, quaternion xyzw)."""
    robot = robot_of(traj)
    model, visual = _models(traj)
    q = pin.neutral(model)
    for name, value in zip(robot.joint_names, traj.q[k], strict=True):
        q[model.joints[model.getJointId(name)].idx_q] = value
    data, vdata = model.createData(), visual.createData()
    pin.forwardKinematics(model, data, q)
    pin.updateGeometryPlacements(model, data, visual, vdata)
    M = vdata.oMg[visual.getGeometryId(geometry)]
    return M.translation, pin.Quaternion(M.rotation).coeffs()


def test_replay_shows_robot_and_paths_and_scrubbing_moves_the_robot(browser: Browser, planned: Path,
                                                                      tmp_path: Path) -> None:
    traj = load(planned)
    page, errors = _open(browser, planned / "replay.html")
    page.wait_for_function("window.singplan && window.singplan.ready", timeout=60_000)
    names = [g.name for g in _models(traj)[1].geometryObjects]
    shown = page.evaluate("() => Object.keys(window.singplan.viewer.scene_tree.children.meshcat.children.robot"
                          ".children.visuals.children)")
    assert sorted(shown) == sorted(names)  # every visual of the URDF is in the scene
    paths = page.evaluate("() => { const p = window.singplan.viewer.scene_tree.children.meshcat.children.paths;"
                          " return [p.children.programmed.children['<object>'].object.type,"
                          " Object.keys(p.children.executed.children)]; }")
    assert paths[0] == "Line"
    assert [name.split("_", 1)[1] for name in paths[1]] == [s.kind for s in traj.segments]
    crossing = next(s for s in traj.segments if s.kind == "crossing")
    assert page.locator("#sp-segments li").count() == len(traj.segments)
    label = page.locator(".sp-label").first.inner_text()
    assert label.startswith(f"{crossing.singularity} crossing, {crossing.method}")

    geometry = names[-1]  # the last link's visual moves most
    step = max(1, round(ANIMATION_STEP_S / traj.period))
    k = round(0.5 * (crossing.t0 + crossing.t1) / traj.period / step) * step  # an animation keyframe
    before = np.array(_node_pose(page, ["meshcat", "robot", "visuals", geometry]))
    page.evaluate("(t) => window.singplan.seek(t)", float(traj.t[k]))
    after = np.array(_node_pose(page, ["meshcat", "robot", "visuals", geometry]))
    p_expected, quat_expected = _expected_pose(traj, k, geometry)
    assert np.linalg.norm(after[:3] - before[:3]) > 0.01  # scrubbing moved the arm
    assert np.allclose(after[:3], p_expected, atol=1e-5)  # ... to the trajectory's pose at that time
    assert min(np.abs(after[3:] - quat_expected).max(), np.abs(after[3:] + quat_expected).max()) < 1e-5
    assert page.evaluate("() => window.singplan.time()") == pytest.approx(traj.t[k], abs=1e-6)
    page.locator("#sp-segments li").nth(traj.segments.index(crossing)).click()  # the list jumps there too
    assert page.evaluate("() => window.singplan.time()") == pytest.approx(0.5 * (crossing.t0 + crossing.t1), abs=0.01)
    page.wait_for_timeout(300)
    shot = tmp_path / "replay.png"
    page.screenshot(path=str(shot))
    assert shot.stat().st_size > 20_000
    saved = os.environ.get("SINGPLAN_SCREENSHOT_DIR")
    if saved:
        shutil.copy(shot, Path(saved) / "replay.png")
    assert errors == []


def test_report_renders_every_plot(browser: Browser, planned: Path) -> None:
    page, errors = _open(browser, planned / "report.html")
    page.wait_for_load_state("load")
    figures = page.locator("figure")
    # joints, speed, distances, deviation, TCP speed, stopping distance, least distance (self-collision)
    assert figures.count() == 7
    for i in range(figures.count()):
        svg = figures.nth(i).locator("svg")
        box = svg.bounding_box()
        assert box is not None and box["width"] > 300 and box["height"] > 100  # laid out, visible
        assert svg.locator("path").count() > 10  # curves and axes were drawn
    assert errors == []
