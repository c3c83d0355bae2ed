"""Regenerate the screenshots of docs/viewer.md: `prefilter view` in headless Debian Chromium (Playwright).

Usage: .venv/bin/python scripts/viewer-docs.py   (writes docs/images/viewer/*.png)
"""

import subprocess
import sys
import time
from pathlib import Path

from playwright.sync_api import sync_playwright

OUT = Path(__file__).resolve().parents[1] / "docs" / "images" / "viewer"
ARGS = ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--ignore-gpu-blocklist"]
ARGS += ["--disable-background-networking", "--disable-component-update", "--disable-sync", "--no-first-run"]
SHOTS = {
    "denim-drape-split": "?scene=normals-denim-drape&mode=multilobe&modeB=naive&split=0.5",
    "zone-plate-split": "?scene=zone-plate&mode=gaussian&modeB=point&split=0.5",
    "diffraction-cd-split": "?scene=diffraction-cd&mode=fast&modeB=naive&split=0.5",
}


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    server = subprocess.Popen(
        [sys.executable, "-m", "prefilter.cli", "view"], stdout=subprocess.PIPE, text=True
    )
    try:
        url = server.stdout.readline().split(": ", 1)[1].strip()
        with sync_playwright() as p:
            browser = p.chromium.launch(executable_path="/usr/bin/chromium", headless=True, args=ARGS)
            page = browser.new_page(viewport={"width": 1400, "height": 860})
            for name, query in SHOTS.items():
                page.goto(url + query)
                page.wait_for_function(
                    "() => window.prefilterViewer && window.prefilterViewer.ready", timeout=180_000
                )
                time.sleep(2)  # a few frames, so the frame time is shown
                page.screenshot(path=str(OUT / f"{name}.png"))
                print(OUT / f"{name}.png")
            browser.close()
    finally:
        server.terminate()


if __name__ == "__main__":
    main()
