"""The WebGL2 viewer in Debian's Chromium (headless, driven by Playwright) against `prefilter view`:
it loads with no console errors and a real WebGL2 context, draws, changes with the mode, matches the
moderngl render of the same view within FLIP 0.05, lists every preset, and serves nothing outside its
root (raw HTTP requests, which browsers would normalise)."""

import http.client
import io
import json
import subprocess
import sys
import urllib.request
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from prefilter.gl.render import Renderer, composite
from prefilter.images import srgb_to_linear
from prefilter.metrics import flip_map
from prefilter.scene import preset_names, resolve_scene

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
# the same view in the browser (es300 shaders through ANGLE/SwiftShader) and in moderngl (gl330, llvmpipe)
FIXED_VIEWS = {
    "marble-cube": "gaussian",
    "terrain-contours": "gaussian",
    "micro-heights-sphere": "surface-filter",
    "normals-hemispheres-plane-shadowed": "multilobe",
    "diffraction-grating-plane": "fast",
}


@pytest.fixture(scope="module")
def server():
    proc = subprocess.Popen(
        [sys.executable, "-m", "prefilter.cli", "view", "--port", "0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    line = proc.stdout.readline()
    if not line.startswith("prefilter viewer: http://127.0.0.1:"):
        proc.kill()
        pytest.fail(f"prefilter view did not start: {line!r} {proc.stderr.read()}")
    url = line.split(": ", 1)[1].strip()
    yield url
    proc.terminate()
    proc.wait(timeout=10)


@pytest.fixture(scope="module")
def browser():
    if not CHROMIUM.exists():
        pytest.fail("Debian's chromium is missing: `make test` installs it (apt-get install -y chromium)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS)
        yield b
        b.close()


class Page:
    """A page of the viewer with its console errors collected."""

    def __init__(self, browser, url: str):
        self.page = browser.new_page()
        self.errors: list[str] = []
        self.page.on("console", lambda m: self.errors.append(m.text) if m.type == "error" else None)
        self.page.on("pageerror", lambda e: self.errors.append(str(e)))
        self.page.goto(url)
        self.wait_ready()

    def wait_ready(self, timeout_ms: int = 120_000) -> None:
        self.page.wait_for_function(
            "() => window.prefilterViewer && (window.prefilterViewer.ready || window.prefilterViewer.error)",
            timeout=timeout_ms,
        )
        error = self.page.evaluate("window.prefilterViewer.error")
        assert error is None, f"viewer error: {error}"

    def canvas(self) -> np.ndarray:
        """The canvas as 8-bit sRGB (H, W, 3)."""
        png = self.page.locator("canvas").first.screenshot()
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB"))

    def close(self) -> None:
        self.page.close()


def test_page_loads_without_console_errors_and_draws(server, browser):
    page = Page(browser, server + "?scene=marble-cube")
    try:
        assert page.page.evaluate("window.prefilterViewer.webgl2") is True
        image = page.canvas()
        background = image[0, 0].astype(int)
        differs = np.abs(image.astype(int) - background).max(axis=-1) > 8
        assert differs.mean() > 0.2, "canvas is (nearly) blank"
        assert image.std() > 10
        assert page.errors == []
    finally:
        page.close()


def test_switching_modes_changes_the_image(server, browser):
    page = Page(browser, server + "?scene=zone-plate&mode=point")
    try:
        point = page.canvas().astype(float)
        page.page.evaluate("window.prefilterViewer.setMode('gaussian')")
        assert page.page.evaluate("window.prefilterViewer.mode") == "gaussian"
        filtered = page.canvas().astype(float)
        assert np.abs(point - filtered).mean() > 2.0, "mode switch did not change the image"
        assert page.errors == []
    finally:
        page.close()


@pytest.mark.parametrize("name", sorted(FIXED_VIEWS) + ["zone-plate", "seascape@0.5"])
def test_fixed_view_matches_the_moderngl_render(name, server, browser):
    """Also an orthographic camera (zone-plate) and the middle of a camera flight (seascape at t = 0.5)."""
    name, _, when = name.partition("@")
    t = float(when or 0.0)
    mode = FIXED_VIEWS.get(name, "gaussian")
    scene = resolve_scene(name)
    w, h = scene.size
    page = Page(browser, server + f"?scene={name}&mode={mode}&fixed=1&t={t}")
    try:
        shot = page.canvas()
        assert page.errors == []
    finally:
        page.close()
    assert shot.shape == (h, w, 3), f"canvas is {shot.shape[1]}x{shot.shape[0]}, scene is {w}x{h}"
    renderer = Renderer(scene)
    try:
        expected = composite(renderer.render(mode, t), scene.background)
        start = composite(renderer.render(mode, 0.0), scene.background)
    finally:
        renderer.release()
    viewer = srgb_to_linear(shot / 255.0).astype(np.float32)
    error = float(flip_map(viewer, np.clip(expected, 0.0, 1.0)).mean())
    print(f"{name} {mode} t={t}: FLIP {error:.5f}")
    if t:  # the flight moved the view: the start of it would not match
        assert float(flip_map(viewer, np.clip(start, 0.0, 1.0)).mean()) > 3 * error
    assert error <= 0.05, f"{name} {mode}: FLIP {error:.4f} > 0.05 between the browser and moderngl"


def test_every_preset_is_offered(server):
    listing = json.loads(urllib.request.urlopen(server.split("?")[0] + "presets.json").read())
    assert [p["name"] for p in listing] == preset_names()


def test_paths_outside_the_root_are_404(server):
    host, port = server.split("//")[1].split("/")[0].split(":")
    for path in (
        "/../pyproject.toml",
        "/%2e%2e/pyproject.toml",
        "/..%2f..%2fetc/passwd",
        "/bundles/marble-cube/../../../pyproject.toml",
        "/bundles/marble-cube/%2e%2e/%2e%2e/etc/passwd",
        "//etc/passwd",
        "/bundles/",
        "/bundles/no-such-scene/scene.json",
        "/",  # served: index.html
    ):
        conn = http.client.HTTPConnection(host, int(port), timeout=120)
        conn.request("GET", path)
        response = conn.getresponse()
        body = response.read()
        conn.close()
        if path == "/":
            assert response.status == 200 and b"<canvas" in body
        else:
            assert response.status == 404, f"{path}: {response.status}"
            assert b"root:" not in body and b"[project]" not in body


def test_directories_are_not_listed(server, browser):
    page = browser.new_page()
    try:
        for path in ("/bundles/marble-cube/", "/bundles/marble-cube/tables/"):
            response = page.goto(server.split("?")[0].rstrip("/") + path)
            assert response.status == 404, path
    finally:
        page.close()


@pytest.mark.parametrize(
    "scene_name, sampler", [("diffraction-grating-plane", "df_terms"), ("marble-cube", "u_tableMip")]
)
def test_the_browser_exr_decoder_reads_exported_tables_exactly(scene_name, sampler, server, browser):
    """web/exr.js against OpenEXR's writer: a 2-channel layered table and a 4-channel MIP level."""
    from prefilter.export import capture_scene

    (captured,) = capture_scene(resolve_scene(scene_name))
    expected = captured.tables[sampler].levels[0]
    depth, height, width, components = expected.shape
    page = browser.new_page()
    try:
        page.goto(server.split("?")[0])
        url = f"/bundles/{scene_name}/tables/{captured.directory}/{sampler}.0.exr"
        result = page.evaluate(
            """async (url) => {
                const {decodeExr} = await import('/exr.js');
                const image = decodeExr(await (await fetch(url)).arrayBuffer());
                const step = Math.ceil(image.data.length / 20000);
                const sample = [];
                let sum = 0;
                for (let i = 0; i < image.data.length; i++) {
                    sum += image.data[i];
                    if (i % step === 0) sample.push(image.data[i]);
                }
                return {width: image.width, height: image.height, channels: image.channels,
                        length: image.data.length, step, sample, sum};
            }""",
            url,
        )
    finally:
        page.close()
    assert (result["width"], result["height"]) == (width, height * depth)
    assert result["channels"] == list("RGBA"[:components])
    flat = expected.ravel()
    assert result["length"] == flat.size
    np.testing.assert_array_equal(np.asarray(result["sample"], np.float32), flat[:: result["step"]])
    assert result["sum"] == pytest.approx(float(flat.astype(np.float64).sum()), rel=1e-9, abs=1e-9)


def test_view_refuses_a_bad_scene_or_a_busy_port_with_one_line(tmp_path, capsys):
    import socket

    from prefilter.cli import main

    bad = tmp_path / "bad.toml"
    bad.write_text("[camera]\nfov = 'wide'\n")
    assert main(["view", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "bad.toml" in err and err.count("\n") == 1
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        assert main(["view", "--port", str(busy.getsockname()[1])]) == 1
    err = capsys.readouterr().err
    assert "cannot listen on 127.0.0.1:" in err and err.count("\n") == 1


def test_view_serves_a_scene_file_given_on_the_command_line(tmp_path):
    """`prefilter view my.toml` lists the file's scene with the presets and prints its address; a file whose
    scene is named like a preset (this copy of marble-cube) gets a name of its own."""
    from prefilter.scene import PRESET_DIR

    scene_file = tmp_path / "my-marble.toml"
    scene_file.write_text((PRESET_DIR / "marble-cube.toml").read_text())
    proc = subprocess.Popen(
        [sys.executable, "-m", "prefilter.cli", "view", str(scene_file)], stdout=subprocess.PIPE, text=True
    )
    try:
        url = proc.stdout.readline().split(": ", 1)[1].strip()
        assert url.endswith("/?scene=marble-cube-file")
        base = url.split("?")[0]
        names = [p["name"] for p in json.loads(urllib.request.urlopen(base + "presets.json").read())]
        assert "marble-cube-file" in names and "marble-cube" in names
        manifest = urllib.request.urlopen(base + "bundles/marble-cube-file/scene.json", timeout=120).read()
        assert json.loads(manifest)["scene"]["name"] == "marble-cube"
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_every_program_of_every_preset_links_in_the_browser(server, browser):
    """ANGLE's translator is stricter than Mesa in places: every (object, mode) es300 program of every
    preset's bundle must compile and link in Chromium's WebGL2."""
    page = browser.new_page()
    try:
        page.goto(server.split("?")[0])
        failures = page.evaluate(
            """async (names) => {
                const gl = document.createElement('canvas').getContext('webgl2');
                if (!gl) return ['no WebGL2 context'];
                const failures = [];
                const compile = (type, source, where) => {
                    const shader = gl.createShader(type);
                    gl.shaderSource(shader, source);
                    gl.compileShader(shader);
                    if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS))
                        failures.push(where + ': ' + gl.getShaderInfoLog(shader).split('\\n')[0]);
                    return shader;
                };
                let programs = 0;
                for (const name of names) {
                    const base = '/bundles/' + name + '/';
                    const scene = await (await fetch(base + 'scene.json')).json();
                    for (const obj of scene.objects) {
                        for (const [mode, targets] of Object.entries(obj.shaders)) {
                            const where = name + ' ' + obj.name + ' ' + mode;
                            const text = async (f) => (await fetch(base + f)).text();
                            const files = targets.es300;
                            const program = gl.createProgram();
                            const vs = await text(files.vertex), fs = await text(files.fragment);
                            gl.attachShader(program, compile(gl.VERTEX_SHADER, vs, where));
                            gl.attachShader(program, compile(gl.FRAGMENT_SHADER, fs, where));
                            gl.linkProgram(program);
                            const log = gl.getProgramInfoLog(program).split('\\n')[0];
                            if (!gl.getProgramParameter(program, gl.LINK_STATUS))
                                failures.push(where + ': link: ' + log);
                            gl.deleteProgram(program);
                            programs++;
                        }
                    }
                }
                return programs > 0 ? failures : ['no programs'];
            }""",
            preset_names(),
        )
    finally:
        page.close()
    assert failures == []


def test_fallbacks_without_float_targets_and_float_filtering_still_match(server, browser):
    """With float render targets and float linear filtering treated as missing (?disable=...), the page
    draws into a 16-bit or 8-bit target and filters tables as 16-bit floats, and still matches moderngl."""
    missing = "EXT_color_buffer_float,EXT_float_blend,OES_texture_float_linear"
    page = Page(browser, server + f"?scene=marble-cube&mode=gaussian&fixed=1&disable={missing}")
    try:
        target = page.page.evaluate("window.prefilterViewer.extensions.target")
        shot = page.canvas()
        assert page.errors == []
    finally:
        page.close()
    assert target in ("RGBA16F", "RGBA8")
    scene = resolve_scene("marble-cube")
    renderer = Renderer(scene)
    try:
        expected = composite(renderer.render("gaussian"), scene.background)
    finally:
        renderer.release()
    error = float(
        flip_map(srgb_to_linear(shot / 255.0).astype(np.float32), np.clip(expected, 0.0, 1.0)).mean()
    )
    print(f"fallback target {target}: FLIP {error:.5f}")
    assert error <= 0.05


def test_a_table_beyond_the_device_limits_is_refused_with_its_name(server, browser):
    page = browser.new_page()
    try:
        page.goto(server.split("?")[0])
        message = page.evaluate(
            """async () => {
                const {createTable, detectExtensions} = await import('/gl-resources.js');
                const gl = document.createElement('canvas').getContext('webgl2');
                const meta = {sampler: 'u_huge', kind: '2d', width: 1 << 20, height: 1, depth: 1,
                              components: 4, levels: [], filter: {min: 'LINEAR', mag: 'LINEAR'}};
                try { createTable(gl, detectExtensions(gl), meta, []); return 'accepted'; }
                catch (e) { return e.message; }
            }"""
        )
    finally:
        page.close()
    assert message.startswith("table u_huge: width and height 1048576x1") and "MAX_TEXTURE_SIZE" in message
