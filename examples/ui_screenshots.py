"""The screenshots of docs/ui.md, taken of the real page in headless Chromium.

    python examples/ui_screenshots.py [OUT_DIR]    # default: here; docs/ui refreshes the docs

default.png   the page on fig. 14 as ``admit-rs ui`` opens it
unstable.png  the page opened from ``?admittance.b=200&wall.stiffness=1e6`` (a stiff wall
              and a light filter damping: it bounces), with fig. 14 pinned as baseline
jupyter.png   ``ar.ui.tuner(...)`` executed in a Jupyter kernel by nbclient, its output cell
              rendered in Chromium
"""

from __future__ import annotations

import html
import os
import sys
import time
from pathlib import Path

import admit_rs as ar
from admit_rs.ui import browser
from admit_rs.ui.server import serve_in_thread


def shoot(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    running = serve_in_thread("fig14", ar.paper.scenario("fig14"))
    drv = browser.driver(1700, 1180)
    try:
        browser.open_page(drv, running.url)
        time.sleep(1.0)
        drv.save_screenshot(str(out / "default.png"))
        browser.click(drv, "pin")  # fig. 14 as the baseline, then the unstable state
        browser.wait(drv, "return Bokeh.documents[0].get_model_by_name('baseline')"
                     ".data.t.length > 0")  # fmt: skip
        drv.execute_script("window.history.replaceState(null, '', "
                           "'/?admittance.b=200&wall.stiffness=1e6');")  # fmt: skip
        for path, value in (("admittance.b", 200.0), ("wall.stiffness", 1e6)):
            drv.execute_script("Bokeh.documents[0].get_model_by_name(arguments[0]).value = "
                               "Math.log10(arguments[1]);", path, value)  # fmt: skip
        browser.wait(drv, "return Bokeh.documents[0].get_model_by_name('verdict').text"
                     ".includes('unstable') && Bokeh.documents[0].get_model_by_name"
                     "('verdict').text.includes('Predicted')", 60)  # fmt: skip
        time.sleep(1.0)
        drv.save_screenshot(str(out / "unstable.png"))
        shoot_jupyter(drv, out)
    finally:
        drv.quit()
        running.stop()


def shoot_jupyter(drv: object, out: Path) -> None:
    import nbformat
    from nbclient import NotebookClient

    source = ("import admit_rs as ar\n"
              "tuner = ar.ui.tuner(ar.paper.scenario('fig19'), height=900)\n"
              "tuner")  # fmt: skip
    nb = nbformat.v4.new_notebook()
    nb.cells = [nbformat.v4.new_code_cell(source)]
    client = NotebookClient(nb, kernel_name="python3", timeout=120)
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(sys.path)}
    with client.setup_kernel(env=env):
        client.execute_cell(nb.cells[0], 0)
        output = next(o["data"]["text/html"] for o in nb.cells[0].outputs if "data" in o)
        page = out / "_notebook.html"
        page.write_text(
            "<html><body style='font-family:system-ui,sans-serif;margin:16px;"
            "background:#fff'><div style='color:#303f9f;font-family:monospace'>[1]:</div>"
            "<pre style='background:#f5f5f5;border:1px solid #e0e0e0;padding:8px;"
            f"font-size:14px'>{html.escape(source)}</pre>"
            "<div style='color:#d84315;font-family:monospace'>[1]:</div>"
            f"{output}</body></html>",
            encoding="utf-8",
        )
        try:
            drv.get(page.as_uri())  # type: ignore[attr-defined]
            frame = drv.find_element("tag name", "iframe")  # type: ignore[attr-defined]
            drv.switch_to.frame(frame)  # type: ignore[attr-defined]
            browser.wait(drv, browser.READY_JS, 60)
            time.sleep(1.0)
            drv.switch_to.default_content()  # type: ignore[attr-defined]
            drv.save_screenshot(str(out / "jupyter.png"))  # type: ignore[attr-defined]
        finally:
            page.unlink()


if __name__ == "__main__":
    shoot(Path(sys.argv[1]) if len(sys.argv) > 1 else Path("."))
