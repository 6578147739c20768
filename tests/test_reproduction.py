"""Generated reports say what docs/reproduction.md says: one claim table (issue 13)."""

from __future__ import annotations

import re
from pathlib import Path

import polars as pl
import pytest
from admit_rs import reproduction
from admit_rs.paper import FIGURES
from admit_rs.reproduction import AGREES, CANNOT, CLAIMS, DIFFERS, Claim

DOCS = Path(__file__).parent.parent / "docs"


@pytest.fixture(scope="module")
def table() -> pl.DataFrame:
    rows = [
        reproduction.metrics_row(name, i, r)
        for name in FIGURES
        for i, r in enumerate(reproduction.run_figure(name))
    ]
    return pl.DataFrame(rows)


def report_rows(report: str) -> list[list[str]]:
    return [[c.strip() for c in line.strip("|").split("|")]
            for line in report.splitlines() if re.match(r"\| fig\d+ \|", line)]  # fmt: skip


def test_every_claim_matches_its_documented_verdict(table):
    judged = reproduction.judge_claims(table)
    assert len(judged) == len(CLAIMS)
    for claim, _, printed in judged:
        assert printed == claim.status, (claim.figure, claim.paper, printed)


def test_no_documented_difference_is_printed_as_agreeing(table):
    report = reproduction._report(table, list(FIGURES), [])
    rows = report_rows(report)
    assert len(rows) == len(CLAIMS)
    documented = {(c.figure, c.paper): c.status for c in CLAIMS}
    differing = 0
    for fig, paper, _, verdict in rows:
        if documented[(fig, paper)] != AGREES:
            differing += 1
            assert not verdict.startswith("agree"), (fig, paper, verdict)
            assert verdict == documented[(fig, paper)]
    assert differing == 10
    # The two rows issue 13 found marked "agrees".
    row = {(r[0], r[1]): r for r in rows}
    assert row[("fig12", "z RMS 3.2052")][2:] == ["z RMS 0.101 m (paper 3.2052)", CANNOT]
    assert row[("fig14", "z RMS 0.0044")][2:] == ["z RMS 0.000261 m (paper 0.0044)", CANNOT]
    assert row[("fig10", "k_a = 2 gives 0.45 % overshoot")][3] == DIFFERS
    assert "## Fig. 12: Nonmodel-based control (Scheme 2), step — agrees in part" in report
    assert ("- Verdict: **MF, Scheme 2, k_a=1: out of tolerance: loss of contact: f = 0 in 36 %"
            in report)


def test_a_stale_claim_is_flagged_never_printed_as_agreeing(table):
    stale = Claim("fig19", "overshoot reduced to ~40 N", DIFFERS,
                  lambda t: ("peak 36 N", True))  # fmt: skip
    measured, printed = stale.judge(table)
    assert printed.startswith("OUT OF DATE: documented as 'differs' but the claim now holds")
    wrong = Claim("fig19", "x", AGREES, lambda t: ("peak 36 N", False))
    assert wrong.judge(table)[1].startswith("OUT OF DATE")


def test_docs_claims_table_is_generated_from_the_claim_table():
    """docs/reproduction.md's summary equals CLAIMS judged on the committed results."""
    doc = (DOCS / "reproduction.md").read_text()
    block = doc.split(reproduction.DOC_BEGIN + "\n", 1)[1].split(reproduction.DOC_END, 1)[0]
    committed = pl.read_parquet(DOCS / "paper-results" / "metrics.parquet")
    assert block == reproduction.claims_markdown(committed)
    for claim in CLAIMS:
        assert f"| {claim.figure} | {claim.paper} |" in block
    generated = (DOCS / "paper-results" / "README.md").read_text()
    assert reproduction.claims_markdown(committed).splitlines()[2] in generated


def test_update_doc_rewrites_only_the_block(tmp_path, table):
    md = tmp_path / "r.md"
    md.write_text(f"intro\n{reproduction.DOC_BEGIN}\nold\n{reproduction.DOC_END}\nrest\n")
    assert reproduction.update_doc(md, table) is True
    text = md.read_text()
    assert text.startswith("intro\n") and text.endswith("rest\n") and "old" not in text
    assert reproduction.update_doc(md, table) is False
