"""Tune by hand, live (SPEC §18): a page where every slider re-simulates and redraws.

``admit-rs ui [SCENARIO.toml | figNN] [--port P] [--no-browser]`` serves it on 127.0.0.1;
:func:`tuner` shows the same page inline in Jupyter. The sliders come from the blocks' field
metadata (:mod:`admit_rs.ui.controls`), the state lives in the URL by dotted path
(``?admittance.b=200&wall.stiffness=1e6``), and everything the page loads comes from the
local server (no CDN: it works offline). Needs the ``ui`` extra (Bokeh):
``pip install '.[ui]'`` from a clone. docs/ui.md shows it.

Example:
    >>> import admit_rs as ar
    >>> t = ar.ui.tuner(ar.paper.scenario("fig14"))   # doctest: +SKIP
    >>> t                                               # doctest: +SKIP
    (the page, inline, in an output cell)
    >>> t.stop()                                        # doctest: +SKIP
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from admit_rs.config import Scenario
from admit_rs.errors import ParameterTypeError
from admit_rs.ui.controls import QueryError, load_base, parse_query, query_string

__all__ = ["QueryError", "Tuner", "load_base", "parse_query", "query_string", "serve", "tuner"]


def _require_bokeh() -> None:
    try:
        import bokeh  # noqa: F401
    except ImportError:
        raise ImportError(
            "the tuning page needs Bokeh: from the clone pip install '.[ui]', or pip install bokeh"
        ) from None


def _start(scenario: Scenario | str | None) -> tuple[str | None, Scenario]:
    """(name for the URL, scenario) of what the page starts from."""
    from admit_rs import paper

    if scenario is None:
        return "fig14", paper.scenario("fig14")
    if isinstance(scenario, str):
        return scenario, load_base(scenario)
    if not isinstance(scenario, Scenario):
        raise ParameterTypeError(f"tuner() takes an admit_rs.Scenario, a figure name or a TOML "
                                 f"path, got {type(scenario).__name__}")  # fmt: skip
    for name, _ in _figure_names():
        if load_base(name) == scenario:
            return name, scenario
    return None, scenario


def _figure_names() -> list[tuple[str, str]]:
    from admit_rs.ui.controls import base_names

    return base_names()


@dataclass
class Tuner:
    """The page served on a background thread of this process; shown inline by Jupyter
    (an ``<iframe>`` of the local page), or open :attr:`url` in a browser. ``stop()``
    ends it."""

    url: str
    height: int = 1250
    _running: Any = field(default=None, repr=False)

    def _repr_html_(self) -> str:
        return (f'<iframe src="{self.url}" width="100%" height="{self.height}" '
                'style="border:0" title="admit_rs tuning page"></iframe>')  # fmt: skip

    def stop(self) -> None:
        """Stops the page's server."""
        if self._running is not None:
            self._running.stop()


def tuner(scenario: Scenario | str | None = None, *, port: int | None = None,
          height: int = 1250) -> Tuner:  # fmt: skip
    """Serves the tuning page for ``scenario`` (a :class:`~admit_rs.Scenario`, a figure
    name such as ``"fig14"`` or a TOML path; default fig. 14) on 127.0.0.1 from a background
    thread, and returns a :class:`Tuner` that Jupyter shows inline. A scenario that is not a
    paper figure's curve has no name in the page's links (its URL carries only the changed
    paths, which this server applies to it)."""
    _require_bokeh()
    from admit_rs.ui.server import serve_in_thread

    name, start = _start(scenario)
    running = serve_in_thread(name, start, port)
    return Tuner(running.url, height, running)


def serve(scenario: Scenario | str | None = None, *, port: int | None = None,
          open_browser: bool = True) -> None:  # fmt: skip
    """Serves the page in the foreground until Ctrl-C (what ``admit-rs ui`` runs)."""
    _require_bokeh()
    from admit_rs.ui.server import serve_forever

    name, start = _start(scenario)
    serve_forever(name, start, port, open_browser)
