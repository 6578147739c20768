"""Slider change -> redrawn plot on the tuning page, in headless Chromium (issue #24).

    python benches/ui_latency.py [--changes 50] [--scenario fig14]
        [--slider admittance.b] [--framework page|panel]

Serves the page (``--framework page``: the real page, plain Bokeh) on a free port of
127.0.0.1, opens it in headless Chromium and moves one slider ``--changes`` times to values
spread over its range, as a drag sets them (the slider model's value, which BokehJS sends to
the server). Each change is timed in the browser from the new value to (a) the new trace
arriving and (b) the first animation frame after it, when BokehJS has repainted the plots.
Between changes it waits for the page to go idle (the prediction also arrives), so each
change is one full round: server run + prediction on two worker threads, transfer, repaint.

``--framework panel`` measures the same thing on a Panel (HoloViz) page with the same five
time plots updated in place (the same data source replaced with the same decimated
columns) and a Panel slider, the run in the slider's callback and no prediction: a lower
bound for a Panel page, for the choice in docs/ui.md.

Prints the median and p90 of both, in ms. Target (SPEC §18): p90 <= 100 ms for fig. 14 on
the 2-core test machine.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time

import numpy as np


def _pct(xs: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(xs), q))


IDLE_JS = """
const m = (n) => Bokeh.documents[0].get_model_by_name(n);
return m('verdict').text.includes('Predicted') && !m('progress').visible;
"""


def bench_page(args: argparse.Namespace) -> list[tuple[float, float]]:
    import admit_rs as ar
    from admit_rs.ui import browser, controls
    from admit_rs.ui.server import serve_in_thread

    base = controls.load_base(args.scenario)
    control = {c.path: c for c in controls.controls(base)}[args.slider]
    lo, hi = control.slider_range
    running = serve_in_thread(args.scenario, base)
    drv = browser.driver()
    try:
        browser.open_page(drv, running.url)
        rng = np.random.default_rng(0)
        positions = lo + (hi - lo) * (0.15 + 0.7 * rng.random(args.changes + args.warmup))
        out = []
        for i, pos in enumerate(positions):
            data_ms, paint_ms = browser.set_and_time(drv, args.slider, float(pos))
            browser.wait(drv, IDLE_JS, 30)
            time.sleep(0.05)
            if i >= args.warmup:
                out.append((data_ms, paint_ms))
        # The last state is what the page shows: check it once against ar.simulate.
        value = control.from_slider(float(positions[-1]))
        sc = base.replace(**{args.slider: value})
        from admit_rs.ui import runs

        full = runs.view_of(sc, ar.simulate(sc).trace, 3)
        expected = runs.decimated(full)["f"]
        shown = np.asarray(browser.column(drv, "trace", "f"))
        assert np.array_equal(shown, expected), "the page's trace is not ar.simulate's"
        return out
    finally:
        drv.quit()
        running.stop()


PANEL_SET_JS = """
const [value, done] = [arguments[0], arguments[arguments.length - 1]];
const doc = Bokeh.documents[0];
const src = doc.get_model_by_name("trace");
let slider = null;
for (const m of doc._all_models.values()) {
  if (m.title === "b" && typeof m.value === "number" && "start" in m) { slider = m; }
}
const t0 = performance.now();
let fired = false;
src.change.connect(() => {
  if (fired) { return; }
  fired = true;
  const t_data = performance.now() - t0;
  requestAnimationFrame(() => done([t_data, performance.now() - t0]));
});
slider.value = value;
setTimeout(() => { if (!fired) { fired = true; done(null); } }, 20000);
"""


def bench_panel(args: argparse.Namespace) -> list[tuple[float, float]]:
    import threading

    import admit_rs as ar
    import panel as pn
    from admit_rs.ui import browser, runs
    from admit_rs.ui.server import free_port
    from bokeh.models import ColumnDataSource
    from bokeh.plotting import figure

    base = ar.paper.scenario(args.scenario)

    def app() -> pn.viewable.Viewable:
        src = ColumnDataSource(data={"t": []}, name="trace")
        plots = []
        for ys in (("f", "f_measured", "f_d"), ("pos_n", "ref_n"), ("pos_t", "ref_t"),
                   ("x_a",), ("tau1", "tau2", "tau3")):  # fmt: skip
            p = figure(width=470, height=210)
            for y in ys:
                p.line("t", y, source=src)
            plots.append(pn.pane.Bokeh(p))
        slider = pn.widgets.FloatSlider(name="b", start=1.0, end=4.0, step=0.01,
                                        value=np.log10(800.0))  # fmt: skip

        def update(value: float) -> None:
            sc = base.replace(**{"admittance.b": float(f"{10**value:.3g}")})
            res = ar.simulate(sc)
            src.data = runs.decimated(runs.view_of(sc, res.trace, 3))  # as the page sends

        slider.param.watch(lambda e: update(e.new), "value")
        update(slider.value)
        return pn.Column(slider, *plots)

    port = free_port()
    server = pn.serve(app, port=port, address="127.0.0.1", show=False, threaded=True,
                      websocket_origin=[f"127.0.0.1:{port}"])  # fmt: skip
    drv = browser.driver()
    try:
        drv.get(f"http://127.0.0.1:{port}/")
        browser.wait(drv, "return window.Bokeh && Bokeh.documents.length && "
                     "Bokeh.documents[0].get_model_by_name('trace').data.t.length > 0", 60)
        rng = np.random.default_rng(0)
        out = []
        for i, pos in enumerate(2.0 + 1.5 * rng.random(args.changes + args.warmup)):
            r = drv.execute_async_script(PANEL_SET_JS, float(pos))
            time.sleep(0.1)
            if i >= args.warmup and r is not None:
                out.append((float(r[0]), float(r[1])))
        return out
    finally:
        drv.quit()
        server.stop()
        _ = threading  # the server ran on its own thread


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--changes", type=int, default=50)
    p.add_argument("--warmup", type=int, default=3)
    p.add_argument("--scenario", default="fig14")
    p.add_argument("--slider", default="admittance.b")
    p.add_argument("--framework", choices=("page", "panel"), default="page")
    args = p.parse_args()
    from admit_rs.ui import browser

    missing = browser.available()
    if missing:
        print(f"cannot run: {missing}", file=sys.stderr)
        return 2
    times = bench_page(args) if args.framework == "page" else bench_panel(args)
    data = [d for d, _ in times]
    paint = [q for _, q in times]
    print(f"{args.framework}, {args.scenario}, slider {args.slider}, {len(times)} changes:")
    print(f"  new trace in the browser: median {statistics.median(data):.1f} ms, "
          f"p90 {_pct(data, 90):.1f} ms")  # fmt: skip
    print(f"  plots repainted:          median {statistics.median(paint):.1f} ms, "
          f"p90 {_pct(paint, 90):.1f} ms, max {max(paint):.1f} ms")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
