"""Driving the tuning page in headless Chromium (Selenium): for the tests, the latency
benchmark and the screenshots of docs/ui.md.

Both binaries are given explicitly (Debian's ``chromium`` and ``chromium-driver``), so
Selenium Manager never runs and nothing is downloaded. :func:`requests` lists every URL the
page asked for (Chrome's performance log), to check that none leaves 127.0.0.1.
"""

from __future__ import annotations

import json
import os
import shutil
import time
from typing import Any

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"

DEEP_TEXT_JS = """
function deep(n) {
  let s = "";
  if (n.shadowRoot) { s += deep(n.shadowRoot); }
  for (const c of n.childNodes) {
    if (c.nodeType === 3) { s += c.textContent; }
    else if (c.nodeType === 1 || c.nodeType === 11) {
      const st = c.nodeType === 1 ? getComputedStyle(c) : null;
      if (st && (st.display === "none" || st.visibility === "hidden")) { continue; }
      s += deep(c) + " ";
    }
  }
  return s;
}
return deep(document.body).replace(/\\s+/g, " ");
"""
"""The page's visible text, through Bokeh's (open) shadow roots."""

MODEL_JS = "return Bokeh.documents[0].get_model_by_name(arguments[0]);"

FIND_VIEW_JS = """
function findView(name) {
  function find(view) {
    if (view.model.name === name) { return view; }
    for (const c of view.child_views || []) { const f = find(c); if (f) { return f; } }
    return null;
  }
  for (const root of Object.values(Bokeh.index)) { const f = find(root); if (f) { return f; } }
  return null;
}
"""
"""``findView(name)``: the view of the named model, in any of the page's roots."""


def click(drv: Any, name: str) -> None:
    """Clicks the button named ``name`` as a user does (its DOM button)."""
    drv.execute_script(FIND_VIEW_JS + "findView(arguments[0]).shadow_el"
                       ".querySelector('button').click();", name)  # fmt: skip


def element(drv: Any, name: str, selector: str) -> Any:
    """The DOM element ``selector`` inside the named model's view (scrolled into view)."""
    return drv.execute_script(FIND_VIEW_JS + "const v = findView(arguments[0]);"
                              "v.el.scrollIntoView({block: 'center'});"
                              "return v.shadow_el.querySelector(arguments[1]);",
                              name, selector)  # fmt: skip


def available() -> str | None:
    """``None`` if Chromium and its driver are installed, else what is missing."""
    missing = [p for p in (CHROMIUM, CHROMEDRIVER) if not (os.path.exists(p) or shutil.which(p))]
    if missing:
        return f"{' and '.join(missing)} not installed (apt-get install chromium chromium-driver)"
    try:
        import selenium  # noqa: F401
    except ImportError:
        return "selenium not installed (from the clone: pip install '.[ui]')"
    return None


def driver(width: int = 1720, height: int = 1300) -> Any:
    """A headless Chromium (``--headless=new --no-sandbox``, as root needs) that logs its
    network requests; no background networking."""
    os.environ.setdefault("SE_AVOID_STATS", "true")
    from selenium import webdriver
    from selenium.webdriver.chrome.options import Options
    from selenium.webdriver.chrome.service import Service

    opts = Options()
    opts.binary_location = CHROMIUM
    for arg in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                f"--window-size={width},{height}", "--disable-background-networking",
                "--disable-component-update", "--disable-default-apps", "--disable-sync",
                "--no-first-run", "--disable-extensions", "--hide-scrollbars",
                "--force-device-scale-factor=1"):  # fmt: skip
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"performance": "ALL", "browser": "ALL"})
    return webdriver.Chrome(service=Service(CHROMEDRIVER), options=opts)


def wait(drv: Any, js: str, timeout: float = 30.0, *args: Any) -> Any:
    """Polls ``js`` (a function body returning a value) until it is truthy; returns it."""
    end = time.monotonic() + timeout
    last: Any = None
    while time.monotonic() < end:
        try:
            last = drv.execute_script(js, *args)
        except Exception as e:  # the page is still loading
            last = e
        if last and not isinstance(last, Exception):
            return last
        time.sleep(0.05)
    raise TimeoutError(f"timed out after {timeout} s waiting for: {js.strip()[:200]} "
                       f"(last: {last!r})")  # fmt: skip


READY_JS = """
if (!window.Bokeh || !Bokeh.documents || !Bokeh.documents.length) { return false; }
const m = (n) => Bokeh.documents[0].get_model_by_name(n);
const v = m("verdict"), e = m("error");
if (!v) { return false; }
const ran = m("trace").data.t && m("trace").data.t.length > 0 && v.text.includes("Predicted");
return ran || (e && e.visible) ? v.text : false;
"""
"""Truthy once the page has drawn its first run and prediction (or shows an error)."""


def open_page(drv: Any, url: str, timeout: float = 60.0) -> str:
    """Loads the page and waits until it has shown its first result; returns the verdict."""
    drv.get(url)
    return str(wait(drv, READY_JS, timeout))


def text(drv: Any) -> str:
    """The page's visible text."""
    return str(drv.execute_script(DEEP_TEXT_JS))


def column(drv: Any, source: str, name: str) -> list[float]:
    """One column of a data source of the page, as the browser holds it."""
    return list(drv.execute_script(
        "const d = Bokeh.documents[0].get_model_by_name(arguments[0]).data[arguments[1]];"
        "return d === undefined ? null : Array.from(d);", source, name))  # fmt: skip


def requests(drv: Any) -> list[str]:
    """URLs of every request the page made since the last call (performance log)."""
    out = []
    for entry in drv.get_log("performance"):
        msg = json.loads(entry["message"])["message"]
        if msg.get("method") in ("Network.requestWillBeSent", "Network.webSocketCreated"):
            params = msg["params"]
            url = params.get("request", {}).get("url") or params.get("url")
            if url:
                out.append(url)
    return out


SET_AND_TIME_JS = """
const [name, value, done] = [arguments[0], arguments[1], arguments[arguments.length - 1]];
const doc = Bokeh.documents[0];
const slider = doc.get_model_by_name(name), src = doc.get_model_by_name("trace");
const t0 = performance.now();
let fired = false;
const slot = () => {
  if (fired) { return; }
  fired = true;
  const t_data = performance.now() - t0;
  requestAnimationFrame(() => done([t_data, performance.now() - t0]));
};
src.change.connect(slot);
slider.value = value;
setTimeout(() => { if (!fired) { fired = true; done(null); } }, 20000);
"""
"""Sets a slider's value as a drag does and times it: [data arrived, plot repainted] in ms
(the repaint is the first animation frame after the new data, when BokehJS paints)."""


def set_and_time(drv: Any, name: str, position: float) -> tuple[float, float]:
    """Moves slider ``name`` to ``position`` (slider units: log10 on log sliders) and returns
    (ms until the new trace arrived, ms until the plots were repainted with it)."""
    out = drv.execute_async_script(SET_AND_TIME_JS, name, position)
    if out is None:
        raise TimeoutError(f"no redraw within 20 s after moving {name}")
    return float(out[0]), float(out[1])
