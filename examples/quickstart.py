"""Quick start: run the paper's fig. 14, change the wall, compare, plot.

    python examples/quickstart.py [OUT_DIR]    # writes OUT_DIR/fig14.png (default: here)
"""

import sys
from pathlib import Path

import admit_rs as ar

out = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(".")
out.mkdir(parents=True, exist_ok=True)

sc = ar.paper.scenario("fig14")  # TDC + Scheme 2 (b = 800, k_a = 1), k_e = 30 000 N/m
print(sc)
res = ar.simulate(sc)
print(res)
print({k: round(v, 4) for k, v in res.metrics.items() if isinstance(v, float)})

# The controller does not know the wall: make it stiffer and misplaced by 1 cm.
stiff = sc.replace(**{"wall.stiffness": 1e5, "wall.position_error": 0.01})
print("peak force with a stiffer, misplaced wall:", ar.simulate(stiff).metrics["force_peak"])

# Bad input fails early, naming the field and the allowed range.
try:
    sc.replace(**{"admittance.b": -1.0})
except ar.ParameterError as e:
    print("ParameterError:", e)

res.plot().savefig(out / "fig14.png", dpi=100)
print("wrote", out / "fig14.png")
