"""The tuning page as a Bokeh document (SPEC §18): one per browser session.

Every slider change sets an override by dotted path, writes the state into the URL and
submits the new scenario to two coalescing workers (:mod:`admit_rs.ui.runs`): the run, whose
trace replaces the plots' data in place, and the prediction (poles, margins, verdict).
Results come back through ``add_next_tick_callback``, the one thread-safe door into a
Bokeh document.
"""

from __future__ import annotations

import base64
import html
import json
import logging
import math
from collections.abc import Callable, Mapping
from functools import partial
from typing import Any

import numpy as np
from bokeh.document import Document
from bokeh.layouts import column, row
from bokeh.models import ColumnDataSource, CustomJS, CustomJSTickFormatter, Range1d
from bokeh.models.annotations import Legend, LegendItem
from bokeh.models.widgets.buttons import Button
from bokeh.models.widgets.inputs import Checkbox, FileInput, Select, TextAreaInput, TextInput
from bokeh.models.widgets.markups import Div
from bokeh.models.widgets.sliders import Slider
from bokeh.plotting import figure

from admit_rs import export
from admit_rs.config import Scenario
from admit_rs.errors import AdmitError
from admit_rs.ui import controls as ctl
from admit_rs.ui import runs, texts

log = logging.getLogger("admit_rs.ui")

REST_DELAY_MS = 40
"""How long after a new trace the page's texts and the prediction follow it."""
PLOT_WIDTH = 470
PLOT_HEIGHT = 210
COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f"]
BASELINE = "#9a9a9a"
LEGEND: dict[str, Any] = {
    "orientation": "horizontal", "location": "top_left", "click_policy": "hide",
    "label_text_font_size": "8pt", "glyph_width": 18, "glyph_height": 10, "label_height": 10,
    "label_standoff": 3, "spacing": 8, "padding": 1, "margin": 2, "border_line_alpha": 0.0,
    "background_fill_alpha": 0.0,
}  # fmt: skip
"""The time plots' legends: one row above the plot area (clicking an entry hides its line)."""

_URL_JS = """
const q = cb_obj.data.query[0];
window.history.replaceState(null, "", window.location.pathname + q);
link.setv({value: window.location.href}, {sync: false});
"""
_UNPACK_JS = """
const v = packed.data.v, names = packed.tags;
if (v === undefined || v.length === undefined || !names.length) { return; }
const n = v.length / names.length, data = {};
for (let i = 0; i < names.length; i++) {
  data[names[i]] = new Float64Array(v.buffer, v.byteOffset + 8 * i * n, n);
}
trace.setv({data}, {sync: false, check_eq: false});
"""
"""The trace arrives as one float64 buffer (``packed``: the columns one after the other,
their names in its tags) and is split here into the plotted source's columns, views of that
buffer. One buffer is 5 WebSocket frames where a column each was 25, handled one by one on
the browser's main thread; ``sync: false`` keeps the browser from sending the columns back."""
_DOWNLOAD_JS = """
if (!cb_obj.data.file[0]) { return; }
const d = JSON.parse(cb_obj.data.file[0]);
const blob = new Blob([d.text], {type: d.type});
const a = document.createElement("a");
a.href = URL.createObjectURL(blob);
a.download = d.name;
document.body.appendChild(a);
a.click();
setTimeout(() => { URL.revokeObjectURL(a.href); a.remove(); }, 1000);
"""
_COPY_JS = """
const href = window.location.href;
link.value = href;
const done = (label) => {
  btn.label = label;
  setTimeout(() => { btn.label = "Copy link"; }, 2000);
};
if (navigator.clipboard && window.isSecureContext) {
  navigator.clipboard.writeText(href).then(() => done("Link copied"),
                                           () => done("Copy the link from the box"));
} else {
  done("Copy the link from the box");
}
"""


TEMPLATE = """
{% extends base %}
{% block contents %}
<style>
  body { margin: 6px 10px; font-family: system-ui, sans-serif; }
  .ar-grid { display: grid; grid-template-columns: 345px 960px 340px; column-gap: 10px; }
</style>
<div>{{ embed(roots.header) }}</div>
<div>{{ embed(roots.status) }}</div>
<div class="ar-grid">
  <div>{{ embed(roots.controls) }}</div>
  <div>{{ embed(roots.plots) }}</div>
  <div>{{ embed(roots.plot_poles) }}{{ embed(roots.pole_text) }}{{ embed(roots.metrics) }}</div>
</div>
<div>{{ embed(roots.export) }}</div>
{% endblock %}
"""
"""The page: header, status, then sliders | plots | poles, pole numbers and metrics."""


def _slider_format(c: ctl.Control) -> CustomJSTickFormatter:
    """Shows the field's value (not log10 of it) with the precision ``from_slider`` keeps."""
    if c.scale == "log":
        code = "return Number((10 ** tick).toPrecision(3)).toString();"
    elif c.integer:
        code = "return Math.round(tick).toString();"
    else:
        step = c.slider_step
        digits = max(0, -math.floor(math.log10(step)) + 1) if step > 0 else 6
        code = f"return Number(tick.toFixed({digits})).toString();"
    return CustomJSTickFormatter(code=code)


def _error_html(message: str) -> str:
    return (
        '<div style="background:#fdecea;border:1px solid #d93025;color:#8c1d18;'
        'padding:6px 10px;border-radius:4px;white-space:pre-wrap;max-width:1000px">'
        f"<b>Error:</b> {html.escape(message)}</div>"
    )


class TuningPage:
    """The state and the widgets of one session's page."""

    def __init__(self, doc: Document, start_name: str | None, start: Scenario,
                 query: Mapping[str, list[str]]) -> None:  # fmt: skip
        self.doc = doc
        self.generation = 0
        self.applied_run = 0
        self.applied_prediction = 0
        self.overrides: dict[str, float | int | None] = {}
        self.base_name: str | None = start_name
        self.base: Scenario = start
        self.current: Scenario | None = None
        self.last_run: runs.RunView | None = None
        self.sim_worker = runs.Coalescer(self._run_job, "admit-rs ui run")
        self.predict_worker = runs.Coalescer(self._predict_job, "admit-rs ui predict")
        self._build_widgets()
        errors: list[str] = []
        name = _first(query.get(ctl.BASE_KEY))
        if name is not None:
            try:
                self.base, self.base_name = ctl.load_base(name), name
            except (AdmitError, ValueError, TypeError) as e:
                errors.append(str(e))
        if not errors:
            self.overrides, errors = ctl.parse_query(query, self.base)
        self._set_base_widgets()
        self._rebuild_controls()
        if errors:
            self._show_error("The link's state cannot be applied:\n" + "\n".join(errors)
                             + "\nMove a slider to run the scenario without it.")  # fmt: skip
            self.verdict.text = "<b>Simulated:</b> not run (see the error)"
        else:
            self._changed(write_url=False)
        doc.on_session_destroyed(self._closed)

    # -- widgets --------------------------------------------------------------------------

    def _build_widgets(self) -> None:
        names = ctl.base_names()
        self._base_names = [n for n, _ in names]
        options: list[Any] = [(n, label) for n, label in names]
        self.picker = Select(title="Scenario", options=options, value=names[0][0], width=330,
                             name="scenario")  # fmt: skip
        self.picker.on_change("value", self._on_pick)
        self.toml_path = TextInput(title="…or a TOML file", placeholder="path/to/scenario.toml",
                                   width=260, name="toml_path")  # fmt: skip
        self.toml_load = Button(label="Load", width=60, name="toml_load")
        self.toml_load.on_click(self._on_load_toml)
        self.toml_upload = FileInput(title="…or upload one", accept=".toml", width=230,
                                     name="toml_upload")  # fmt: skip
        self.toml_upload.on_change("value", self._on_upload)

        self.link = TextInput(title="Link to this state", width=420, name="link")
        self.copy = Button(label="Copy link", width=110, name="copy_link")
        self.copy.js_on_click(CustomJS(args={"link": self.link, "btn": self.copy}, code=_COPY_JS))
        # The URL and downloads go through data sources, not Divs: a Div's text change
        # re-lays out the whole page (~25 ms here), a source's data does not.
        self.url_state = ColumnDataSource(data={"query": [""]}, name="url_state")
        self.url_state.js_on_change("data", CustomJS(args={"link": self.link}, code=_URL_JS))
        self.doc.js_on_event("document_ready", CustomJS(args={"link": self.link},
                             code="link.value = window.location.href;"))  # fmt: skip
        self.download = ColumnDataSource(data={"file": [""]}, name="download")
        self.download.js_on_change("data", CustomJS(code=_DOWNLOAD_JS))

        self.pin = Button(label="Pin as baseline", width=130, name="pin")
        self.pin.on_click(self._on_pin)
        self.unpin = Button(label="Clear baseline", width=120, name="unpin")
        self.unpin.on_click(self._on_unpin)
        self.export_toml = Button(label="Export TOML", width=110, name="export_toml")
        self.export_toml.on_click(partial(self._on_export, "toml"))
        self.export_ros = Button(label="Export ROS 2 YAML", width=150, name="export_ros2")
        self.export_ros.on_click(partial(self._on_export, "ros2"))
        self.export_text = TextAreaInput(title="Export", rows=10, width=960, name="export",
                                         visible=False)  # fmt: skip

        self.verdict = Div(text="", width=1600, name="verdict")
        self.error = Div(text="", width=960, name="error", visible=False)
        self.progress = Div(text="", width=600, name="progress", visible=False)
        self.cancel = Button(label="Cancel run", width=110, name="cancel", visible=False,
                             button_type="warning")  # fmt: skip
        self.cancel.on_click(self._on_cancel)
        self.metrics = Div(text="", width=335, name="metrics")
        self.pole_text = Div(text="", width=335, name="pole_text")
        self.controls_box = column(name="controls", width=340)

        self.trace = ColumnDataSource(data=_empty(), name="trace")
        self.packed = ColumnDataSource(data={"v": np.zeros(0)}, name="packed")
        unpack = CustomJS(args={"packed": self.packed, "trace": self.trace}, code=_UNPACK_JS)
        self.packed.js_on_change("data", unpack)
        self.doc.js_on_event("document_ready", unpack)
        self.baseline = ColumnDataSource(data=_empty(), name="baseline")
        self.limits = ColumnDataSource(data={"xs": [], "ys": [], "color": []}, name="limits")
        self.poles = ColumnDataSource(data={"re": [], "im": [], "mag": []}, name="poles")
        self.dominant = ColumnDataSource(data={"re": [], "im": []}, name="dominant")
        self._build_plots()

    def _time_plot(self, title: str, y_label: str, name: str, x_range: Any = None) -> Any:
        kw: dict[str, Any] = {"x_range": x_range} if x_range is not None else {}
        p = figure(title=title, width=PLOT_WIDTH, height=PLOT_HEIGHT, name=name,
                   tools="pan,wheel_zoom,box_zoom,reset,save", x_axis_label="t [s]",
                   y_axis_label=y_label, **kw)  # fmt: skip
        p.toolbar.logo = None
        # Above the plot area, not in it: a legend never covers the traces. Its entries
        # come from :func:`_line`.
        p.add_layout(Legend(**LEGEND), "above")
        return p

    def _tip_plot(self, title: str, y_label: str, name: str, axis: str, x_range: Any) -> Any:
        """The tip along one task axis (``"n"`` or ``"t"``): baseline, reference and tip."""
        src, base = self.trace, self.baseline
        p = self._time_plot(title, y_label, name, x_range)
        _line(p, f"pos_{axis}", base, "baseline", color=BASELINE, line_dash="dashed")
        _line(p, f"ref_{axis}", src, "reference", color="black", line_dash="dashed")
        _line(p, f"pos_{axis}", src, "tip", color=COLORS[0])
        return p

    def _build_plots(self) -> None:
        src, base = self.trace, self.baseline
        f = self._time_plot("Force along n", "f [N]", "plot_force")
        _line(f, "f", base, "baseline f", color=BASELINE, line_dash="dashed")
        _line(f, "f_measured", src, "f measured", color=COLORS[1], alpha=0.7)
        _line(f, "f", src, "f (true)", color=COLORS[0], line_width=1.5)
        _line(f, "f_d", src, "f_d", color="black", line_dash="dashed")
        x = f.x_range
        pn = self._tip_plot("Tip along n", "n·X [m]", "plot_normal", "n", x)
        pt = self._tip_plot("Tip along t̂", "t̂·X [m]", "plot_tangent", "t", x)
        xa = self._time_plot("Filter output x_a", "x_a [m]", "plot_xa", x)
        _line(xa, "x_a", base, "baseline", color=BASELINE, line_dash="dashed")
        _line(xa, "x_a", src, "x_a", color=COLORS[2])
        self.torque_plot = self._time_plot("Joint torques (applied) and limits", "τ [N·m]",
                                           "plot_torque", x)  # fmt: skip
        self.torque_plot.multi_line("xs", "ys", source=self.limits, color="color",
                                    line_dash="dotted", line_width=1.5)  # fmt: skip
        self.torque_lines: list[Any] = []
        poles = figure(title="Predicted poles (z-plane)", width=330, height=330,
                       x_range=Range1d(start=-1.15, end=1.15),
                       y_range=Range1d(start=-1.15, end=1.15),
                       match_aspect=True, tools="pan,wheel_zoom,box_zoom,reset",
                       name="plot_poles")  # fmt: skip
        poles.toolbar.logo = None
        theta = np.linspace(0, 2 * np.pi, 361)
        poles.line(np.cos(theta), np.sin(theta), color="black", line_width=1)
        poles.scatter("re", "im", source=self.poles, size=7, color=COLORS[0], alpha=0.8)
        poles.scatter("re", "im", source=self.dominant, size=14, marker="x",
                      color=COLORS[3], line_width=2.5)  # fmt: skip
        self.pole_plot = poles
        self.plots = column(row(f, pn), row(pt, xa), row(self.torque_plot))

    def add_roots(self) -> None:
        """The page as separate Bokeh roots placed by :data:`TEMPLATE`: a change of text
        (verdict, metrics) or of the sliders re-lays out only its own root, not the plots
        (a Div's new text re-lays out its whole root: ~25 ms for one root holding all)."""

        def pad() -> Div:
            return Div(text="", height=12)

        header = column(
            row(Div(text="<h2 style='margin:4px 0'>admit_rs — tune by hand</h2>", width=300),
                self.picker, self.toml_path, column(pad(), self.toml_load), self.toml_upload),
            row(column(pad(), self.pin), column(pad(), self.unpin),
                self.link, column(pad(), self.copy),
                column(pad(), self.export_toml),
                column(pad(), self.export_ros)),
            name="header",
        )  # fmt: skip
        self.plots.name = "plots"
        status = column(self.verdict, self.error, row(self.progress, self.cancel),
                        name="status")  # fmt: skip
        # TEMPLATE places each root by its name.
        for root in (header, status, self.controls_box, self.plots, self.pole_plot,
                     self.pole_text, self.metrics, self.export_text):  # fmt: skip
            self.doc.add_root(root)
        # Not roots (every root must be placed in the page): held by the header instead.
        header.tags = [self.url_state, self.download, self.packed]
        from jinja2 import Template

        self.doc.template = Template(TEMPLATE)

    # -- controls -------------------------------------------------------------------------

    def _set_base_widgets(self) -> None:
        if self.base_name in self._base_names:
            self.picker.value = self.base_name
        elif self.base_name is not None:
            self.toml_path.value = self.base_name

    def _rebuild_controls(self) -> None:
        shown = self.base.replace(**self.overrides) if self.overrides else self.base
        children: list[Any] = []
        block = None
        self.sliders: dict[str, Slider] = {}
        for c in ctl.controls(shown):
            if c.block != block:
                block = c.block
                children.append(Div(text=f"<b>{html.escape(block)}</b>", margin=(8, 5, 0, 5)))
            children.append(self._control_widget(c))
        self.controls_box.children = children

    def _control_widget(self, c: ctl.Control) -> Any:
        lo, hi = c.slider_range
        value = c.to_slider(c.value if c.value is not None else (c.low if c.scale == "log"
                                                                  else c.low))  # fmt: skip
        title = c.title + (" (per joint: " + ", ".join(texts.number(v, 3) for v in c.per_joint)
                           + ")" if c.per_joint else "")  # fmt: skip
        slider = Slider(start=lo, end=hi, value=value, step=c.slider_step, title=title,
                        format=_slider_format(c), width=300, name=c.path,
                        disabled=c.value is None, show_value=c.value is not None,
                        tags=[c.scale], html_attributes={"title": c.doc})  # fmt: skip
        if c.value is None:
            slider.title = f"{title} (off)"
        slider.on_change("value", partial(self._on_slider, c))
        self.sliders[c.path] = slider
        if not c.nullable:
            return slider
        box = Checkbox(label="on", active=c.value is not None, width=40, name=c.path + ":on",
                       margin=(22, 0, 0, 5))  # fmt: skip
        box.on_change("active", partial(self._on_toggle, c, slider))
        return row(box, slider)

    def _on_slider(self, c: ctl.Control, attr: str, old: Any, new: Any) -> None:
        self.overrides[c.path] = c.from_slider(float(new))
        self._changed()

    def _on_toggle(self, c: ctl.Control, slider: Slider, attr: str, old: Any, new: Any) -> None:
        slider.disabled = not new
        slider.show_value = bool(new)
        slider.title = c.title if new else f"{c.title} (off)"
        self.overrides[c.path] = c.from_slider(float(slider.value)) if new else None
        self._changed()

    def _on_pick(self, attr: str, old: Any, new: Any) -> None:
        if new == self.base_name:
            return
        self._switch_base(str(new))

    def _on_load_toml(self) -> None:
        path = self.toml_path.value.strip()
        if not path:
            self._show_error("Type the path of a TOML scenario file first.")
            return
        self._switch_base(path)

    def _on_upload(self, attr: str, old: Any, new: Any) -> None:
        # The browser sets value, filename and mime type in one message, value first: read
        # them once all are applied.
        if new:
            self.doc.add_next_tick_callback(self._load_upload)

    def _load_upload(self) -> None:
        value, filename = self.toml_upload.value, self.toml_upload.filename or "(unnamed)"
        if not isinstance(value, str) or not value:
            return
        try:
            name = ctl.register_upload(base64.b64decode(value, validate=True), str(filename))
        except (AdmitError, ValueError, TypeError) as e:
            self._show_error(str(e))
            return
        self._switch_base(name)

    def _switch_base(self, name: str) -> None:
        try:
            base = ctl.load_base(name)
        except (AdmitError, ValueError, TypeError) as e:
            self._show_error(str(e))
            return
        self.base, self.base_name, self.overrides = base, name, {}
        self._rebuild_controls()
        self._changed()

    # -- state → work ---------------------------------------------------------------------

    def _changed(self, write_url: bool = True) -> None:
        """The state changed: check it, put it in the URL, submit it to both workers."""
        try:
            scenario = self.base.replace(**self.overrides) if self.overrides else self.base
        except (AdmitError, ValueError, TypeError) as e:
            self._show_error(str(e))
            self.verdict.text = "<b>Simulated:</b> not run (see the error)"
            return
        self.current = scenario
        self.generation += 1
        self.sim_worker.submit(self.generation, scenario)  # first: the run is the long part
        self.url_state.data = {"query": [ctl.query_string(self.base_name, self.overrides)]}

    def _next_tick(self, fn: Callable[[], None]) -> None:
        try:
            self.doc.add_next_tick_callback(fn)
        except Exception:  # the session is gone: nothing to show it in
            log.debug("admit-rs ui: session closed before a result arrived")

    def _run_job(self, job: runs.Job) -> None:
        shown = False
        try:
            shown = self._run_and_show(job)
        finally:
            if not shown and (not job.stale() or job.cancelled):
                self.predict_worker.submit(job.generation, job.scenario)

    def _run_and_show(self, job: runs.Job) -> bool:
        """Runs the job; True when its trace went to the page (which then starts the
        prediction, see :meth:`_show_rest`)."""
        def progress(done: float, total: float) -> None:
            self._next_tick(partial(self._show_progress, job.generation, done, total))

        try:
            view = runs.run(job, progress)
        except (AdmitError, ValueError, TypeError) as e:
            self._next_tick(partial(self._show_run_error, job.generation, str(e)))
            return False
        except Exception as e:  # not the user's input: say so, keep the trace for the log
            log.exception("admit-rs ui: the run failed")
            self._next_tick(partial(self._show_run_error, job.generation,
                                    f"internal error ({type(e).__name__}): {e}"))  # fmt: skip
            return False
        if view is None:
            return False
        view.plotted = runs.decimated(view.columns)
        self._next_tick(partial(self._show_run, job, view))
        return True

    def _predict_job(self, job: runs.Job) -> None:
        try:
            pred = runs.predict(job.scenario)
        except Exception as e:
            log.exception("admit-rs ui: the prediction failed")
            pred = runs.Prediction(None, None, f"internal error ({type(e).__name__}): {e}")
        self._next_tick(partial(self._show_prediction, job.generation, pred))

    # -- work → page (on the document's thread) -------------------------------------------

    def _show_error(self, message: str) -> None:
        self.error.text = _error_html(message)
        self.error.visible = True

    def _clear_error(self) -> None:
        if self.error.visible:
            self.error.visible = False
            self.error.text = ""

    def _show_progress(self, generation: int, done: float, total: float) -> None:
        if generation < self.generation or generation <= self.applied_run:
            return
        pct = 100 * done / total if total > 0 else 0
        self.progress.text = (
            f"<b>Running:</b> {done:.1f} of {total:.1f} s ({pct:.0f} %) "
            f'<progress value="{pct:.0f}" max="100" style="width:200px"></progress>'
        )
        self.progress.visible = True
        self.cancel.visible = True

    def _hide_progress(self) -> None:
        self.progress.visible = False
        self.cancel.visible = False

    def _show_run_error(self, generation: int, message: str) -> None:
        if generation < self.applied_run:
            return
        self.applied_run = generation
        self._hide_progress()
        self._show_error(message)
        self.verdict.text = "<b>Simulated:</b> failed (see the error)" + self._predicted_html

    def _show_run(self, job: runs.Job, view: runs.RunView) -> None:
        """The new trace now; the words, the metrics and the prediction a moment later
        (:data:`REST_DELAY_MS`), so that the browser's first work is the plots' redraw (on
        two cores shared by server, browser and often more, every text re-layout and the
        prediction's thread compete with it)."""
        if job.generation < self.applied_run:
            return
        self._set_torque_lines(view.joints)
        self.plotted = view.plotted if view.plotted is not None else view.columns
        names = list(self.plotted)
        if self.packed.tags != names:
            self.packed.tags = names
        self.packed.data = {"v": np.concatenate([self.plotted[k] for k in names])}
        self.doc.add_timeout_callback(partial(self._show_rest, job, view), REST_DELAY_MS)

    def _show_rest(self, job: runs.Job, view: runs.RunView) -> None:
        if not job.stale() or job.cancelled:
            self.predict_worker.submit(job.generation, job.scenario)
        if job.generation < self.applied_run:
            return
        generation = self.applied_run = job.generation
        if generation == self.generation:
            self._hide_progress()
        self._clear_error()
        self.last_run = view
        xs, ys, color = [], [], []
        if view.torque_limits is not None:
            for j, lim in enumerate(view.torque_limits):
                for sign in (1.0, -1.0):
                    xs.append([0.0, view.duration])
                    ys.append([sign * lim, sign * lim])
                    color.append(COLORS[j % len(COLORS)])
        if xs or self.limits.data["xs"]:
            self.limits.data = {"xs": xs, "ys": ys, "color": color}
        self._sim_html = texts.simulated_html(view)
        self._last_view = (generation, view)
        self.verdict.text = self._sim_html + self._predicted_html + self._why_html()
        self.metrics.text = texts.metrics_html(view)

    def _set_torque_lines(self, joints: int) -> None:
        if len(self.torque_lines) == 2 * joints:  # each a line and its legend's stand-in
            return
        p = self.torque_plot
        keep = [r for r in p.renderers if r not in self.torque_lines]
        legend = p.legend[0]
        legend.items = []
        lines = [_line(p, f"tau{j}", self.trace, f"τ{j}", color=COLORS[(j - 1) % len(COLORS)])
                 for j in range(1, joints + 1)]  # fmt: skip
        self.torque_lines = [r for pair in lines for r in pair]
        p.renderers = keep + self.torque_lines

    _sim_html = ""
    _predicted_html = ""
    _last_view: tuple[int, runs.RunView] | None = None
    _last_prediction: tuple[int, runs.Prediction] | None = None

    def _why_html(self) -> str:
        """When the simulated and predicted ``stable`` (or ``passed``) of one scenario (one
        generation) differ, why, in one line each."""
        if self._last_view is None or self._last_prediction is None:
            return ""
        (ran, view), (predicted, pred) = self._last_view, self._last_prediction
        if ran != predicted:
            return ""
        out = ""
        why = runs.disagreement(view, pred)
        if why is not None:
            out += f"<br><b>Why they differ:</b> <span class='why'>{html.escape(why)}</span>"
        why = runs.passed_disagreement(view, pred)
        if why is not None:
            out += (f"<br><b>Why passed differs:</b> <span class='why-passed'>"
                    f"{html.escape(why)}</span>")  # fmt: skip
        return out
    _exports = 0

    def _show_prediction(self, generation: int, pred: runs.Prediction) -> None:
        if generation < self.applied_prediction:
            return
        self.applied_prediction = generation
        self._predicted_html = texts.prediction_html(pred)
        self._last_prediction = (generation, pred)
        self.verdict.text = ((self._sim_html or "<b>Simulated:</b> running…")
                             + self._predicted_html + self._why_html())  # fmt: skip
        dom = pred.dominant()
        if pred.poles is not None and dom is not None:
            p = pred.poles
            self.poles.data = {"re": p.real, "im": p.imag, "mag": np.abs(p)}
            self.dominant.data = {"re": [dom.real], "im": [dom.imag]}
        else:
            self.poles.data = {"re": [], "im": [], "mag": []}
            self.dominant.data = {"re": [], "im": []}
        self.pole_text.text = texts.pole_html(pred)

    def _on_pin(self) -> None:
        if self.last_run is not None:
            self.baseline.data = dict(self.plotted)

    def _on_unpin(self) -> None:
        self.baseline.data = _empty()

    def _on_cancel(self) -> None:
        if self.sim_worker.cancel():
            self.progress.text = "<b>Cancelling…</b>"

    def _on_export(self, what: str) -> None:
        sc = self.current
        if sc is None:
            self._show_error("Nothing to export: the current state is not a valid scenario.")
            return
        try:
            if what == "toml":
                text, name, mime = export.toml(sc), "scenario.toml", "application/toml"
            else:
                import warnings

                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    text = export.ros2_admittance(sc, None)
                notes = [f"# warning: {w.message}" for w in caught]
                text = "\n".join(notes + [text]) if notes else text
                name, mime = "admittance.yaml", "application/yaml"
        except (AdmitError, ValueError, TypeError) as e:
            self._show_error(f"Export as {'TOML' if what == 'toml' else 'ROS 2 YAML'}: {e}")
            return
        self._clear_error()
        self.export_text.title = f"Export: {name}"
        self.export_text.value = text
        self.export_text.visible = True
        self._exports += 1  # a new value each time: the same file twice is two downloads
        self.download.data = {"file": [json.dumps({"name": name, "type": mime, "text": text,
                                                   "n": self._exports})]}  # fmt: skip

    def _closed(self, session_context: Any) -> None:
        self.sim_worker.close()
        self.predict_worker.close()


_FOLLOW_JS = """
const line = cb_obj.document.get_model_by_id(line_id);
if (line != null) { line.visible = cb_obj.visible; }
"""


def _line(p: Any, y: str, source: ColumnDataSource, label: str, **style: Any) -> tuple[Any, Any]:
    """Draws column ``y`` of ``source`` against ``t`` on ``p``, with a legend entry.

    The entry is drawn by a stand-in renderer of the same style and no data, not by the
    line itself: BokehJS re-renders a legend on every change of anything its entries
    reach (a line's data source too), a new small canvas per entry and a re-layout of the
    plot, 10–20 ms for each new trace. Clicking the entry hides the stand-in, and the line
    follows it (found by id, not held: holding it would reach the data again).
    Returns (line, stand-in)."""
    line = p.line("t", y, source=source, name=f"{p.name}:{source.name}:{y}", **style)
    # One NaN point: nothing on the plot or in its ranges, but a sample for the legend's
    # glyph (an empty source draws an empty one).
    nan = float("nan")
    stand_in = p.line("x", "y", source=ColumnDataSource(data={"x": [nan], "y": [nan]}), **style)
    stand_in.js_on_change("visible", CustomJS(args={"line_id": line.id}, code=_FOLLOW_JS))
    p.legend[0].items.append(LegendItem(label=label, renderers=[stand_in]))
    return line, stand_in


def _empty() -> dict[str, list[float]]:
    """A source with every column the time plots draw (but the torques), no samples."""
    names = ("t", "f", "f_measured", "f_d", "pos_n", "ref_n", "pos_t", "ref_t", "x_a")
    return {n: [] for n in names}


def _first(values: list[str] | None) -> str | None:
    return values[-1] if values else None


def build(doc: Document, start_name: str | None, start: Scenario) -> None:
    """Fills ``doc`` with the page for the session's request (its URL query)."""
    query: dict[str, list[str]] = {}
    ctx = doc.session_context
    request = getattr(ctx, "request", None) if ctx is not None else None
    if request is not None:
        for key, values in request.arguments.items():
            query[key] = [v.decode("utf-8", "replace") for v in values]
    page = TuningPage(doc, start_name, start, query)
    doc.title = "admit_rs tuning"
    page.add_roots()
