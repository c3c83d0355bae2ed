"""`prefilter view`: serve the WebGL2 viewer (web/) and the export bundles it draws, on 127.0.0.1 only.

Routes: `/` and the files of web/; `/presets.json` (every preset, plus the scene given on the command
line); `/bundles/<name>/<file>`: the export bundle of a scene (docs/export.md), written on first request
into a temporary directory that lives as long as the server. Nothing outside those two roots is served:
paths are resolved and must stay inside their root, directories are never listed, and anything else is
a 404. GL work (bakes, read-backs) runs on one worker thread, which owns the process's GL context.
"""

from __future__ import annotations

import functools
import json
import shutil
import sys
import tempfile
import threading
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from http import HTTPStatus
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import unquote, urlsplit

from prefilter import PrefilterError
from prefilter.geometry import REPO_ROOT
from prefilter.scene import Scene, preset_names, resolve_scene

WEB_ROOT = REPO_ROOT / "web"
CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".json": "application/json",
    ".md": "text/markdown; charset=utf-8",
    ".vert": "text/plain; charset=utf-8",
    ".frag": "text/plain; charset=utf-8",
    ".png": "image/png",
    ".exr": "application/octet-stream",
    ".bin": "application/octet-stream",
}


def inside(root: Path, relative: str) -> Path | None:
    """The regular file `relative` under `root`, or None if it is missing, a directory or outside root."""
    if "\0" in relative:
        return None
    root = root.resolve()
    candidate = (root / relative.lstrip("/")).resolve()
    if not candidate.is_relative_to(root) or not candidate.is_file():
        return None
    return candidate


class Bundles:
    """Export bundles of the presets (and of one extra scene file), made on first request, one at a time."""

    def __init__(self, extra: str | None):
        self.sources = {name: name for name in preset_names()}
        self.first: str | None = None
        if extra is not None:
            scene = resolve_scene(extra)  # fails early, with the scene file's own error
            name = scene.name
            while self.sources.get(name, extra) != extra:  # a scene file named like a preset
                name += "-file"
            self.sources[name] = extra
            self.first = name
        self.root = Path(tempfile.mkdtemp(prefix="prefilter-viewer-"))
        self.errors: dict[str, str] = {}
        self.gl = ThreadPoolExecutor(max_workers=1, thread_name_prefix="prefilter-gl")
        self.lock = threading.Lock()

    @functools.cached_property
    def listing(self) -> list[dict]:
        """Name, description and tags of every scene (parsed once: bundles are made once too)."""
        out = []
        for name, source in self.sources.items():
            try:
                scene = resolve_scene(source)
            except PrefilterError as exc:
                out.append({"name": name, "description": f"error: {exc}", "tags": []})
                continue
            out.append({"name": name, "description": scene.description, "tags": list(scene.tags)})
        return out

    def _export(self, name: str) -> Path:
        from prefilter.export import export_scene

        scene: Scene = resolve_scene(self.sources[name])
        return export_scene(scene, self.root / name)

    def ensure(self, name: str) -> Path:
        """The bundle directory of `name`, exporting it first if needed; PrefilterError if that fails."""
        with self.lock:
            if name in self.errors:
                raise PrefilterError(self.errors[name])
            path = self.root / name
            if (path / "scene.json").is_file():
                return path
            try:
                return self.gl.submit(self._export, name).result()
            except PrefilterError as exc:
                self.errors[name] = str(exc)
                raise

    def close(self) -> None:
        self.gl.shutdown(wait=False, cancel_futures=True)
        shutil.rmtree(self.root, ignore_errors=True)


class ViewerHandler(SimpleHTTPRequestHandler):
    server_version = "prefilter-viewer"

    def __init__(self, *args, bundles: Bundles, **kwargs):
        self.bundles = bundles
        super().__init__(*args, directory=str(WEB_ROOT), **kwargs)

    def log_message(self, format: str, *args) -> None:  # noqa: A002 (the base class's name)
        if args and str(args[1]).startswith(("4", "5")):
            sys.stderr.write(f"prefilter view: {self.address_string()} {format % args}\n")

    def _send(self, status: int, body: bytes, content_type: str, head: bool = False) -> None:
        self.send_response(status)
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("X-Content-Type-Options", "nosniff")
        self.end_headers()
        if not head:
            self.wfile.write(body)

    def _not_found(self, head: bool) -> None:
        self._send(HTTPStatus.NOT_FOUND, b"not found\n", "text/plain; charset=utf-8", head)

    def _file(self, path: Path | None, head: bool) -> None:
        if path is None:
            return self._not_found(head)
        content_type = CONTENT_TYPES.get(path.suffix.lower(), "application/octet-stream")
        self._send(HTTPStatus.OK, path.read_bytes(), content_type, head)

    def _route(self, head: bool) -> None:
        path = unquote(urlsplit(self.path).path)
        if path in ("", "/"):
            return self._file(inside(WEB_ROOT, "index.html"), head)
        if path == "/presets.json":
            listing = json.dumps(self.bundles.listing).encode()
            return self._send(HTTPStatus.OK, listing, CONTENT_TYPES[".json"], head)
        if path.startswith("/bundles/"):
            name, _, rest = path[len("/bundles/") :].partition("/")
            if name not in self.bundles.sources or not rest:
                return self._not_found(head)
            try:
                root = self.bundles.ensure(name)
            except PrefilterError as exc:
                body = json.dumps({"error": str(exc)}).encode()
                return self._send(HTTPStatus.INTERNAL_SERVER_ERROR, body, CONTENT_TYPES[".json"], head)
            return self._file(inside(root, rest), head)
        return self._file(inside(WEB_ROOT, path), head)

    def do_GET(self) -> None:  # noqa: N802 (http.server's naming)
        self._route(head=False)

    def do_HEAD(self) -> None:  # noqa: N802
        self._route(head=True)


def make_server(scene: str | None = None, port: int = 0) -> tuple[ThreadingHTTPServer, Bundles, str]:
    if not (WEB_ROOT / "index.html").is_file():
        raise PrefilterError(f"{WEB_ROOT}: the viewer's files are missing (index.html)")
    bundles = Bundles(scene)
    try:
        server = ThreadingHTTPServer(("127.0.0.1", port), partial(ViewerHandler, bundles=bundles))
    except OSError as exc:
        bundles.close()
        raise PrefilterError(f"cannot listen on 127.0.0.1:{port}: {exc.strerror}") from None
    url = f"http://127.0.0.1:{server.server_address[1]}/"
    if bundles.first:
        url += f"?scene={bundles.first}"
    return server, bundles, url


def serve(scene: str | None = None, port: int = 0) -> None:
    server, bundles, url = make_server(scene, port)
    print(f"prefilter viewer: {url}", flush=True)
    try:
        server.serve_forever()
    except KeyboardInterrupt:
        pass
    finally:
        server.server_close()
        bundles.close()
