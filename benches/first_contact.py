"""The cost of the guarded approach and the adaptive filter (issue #23): a 10-s fig. 14 run
plain, with ``AdmittanceFilter.adaptive`` and with ``GuardedApproach()``, scalar
(``ar.simulate``, best of ``--repeat`` rounds) and in lanes (``ar.sweep`` of ``--samples`` runs over
the wall stiffness, no traces, best of every fifth round).

    python benches/first_contact.py [--repeat 15] [--samples 64]

The ratio to the plain run is what docs/performance-history.md §13 states (target ≤ 1.1×).
"""

from __future__ import annotations

import admit_rs as ar
import ratios


def cases() -> dict[str, ar.Scenario]:
    fig14 = ar.paper.scenario("fig14")
    return {
        "plain fig. 14": fig14,
        "adaptive filter": fig14.replace(admittance=ar.AdmittanceFilter.adaptive()),
        "guarded approach": fig14.replace(approach=ar.GuardedApproach()),
        "guarded approach, 5 mm gap": fig14.replace(
            approach=ar.GuardedApproach(), **{"wall.gap": 0.005}),
        "guarded approach, velocity steps": fig14.replace(
            approach=ar.GuardedApproach(acceleration=None)),
    }


if __name__ == "__main__":
    ratios.main(cases())
