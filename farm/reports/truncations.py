"""Runs that left Sigma through a truncating facet: they end quietly and count as safe
(shared/spec/scenarios.md). Right when the facet is not of concern (the lead drove out
of range); a silent wrong answer when a simulator leaves Sigma where the study did not
expect it (a stopped vehicle reversing through v >= 0 before it collides). So the
campaign counts them per facet (summary.json ``truncations``) and says so when a facet
takes a noticeable share of the committed runs."""

from __future__ import annotations

from farm.reports.summary import Summary

NOTICEABLE_SHARE = 0.01  # of the committed runs: below this the CLI stays silent


def shares(summary: Summary) -> list[tuple[str, int, float]]:
    """(facet, runs, share of committed runs) for every truncating facet, most first."""
    committed = max(summary.runs_committed, 1)
    counts = summary.truncations or {}
    return sorted(((facet, int(n), int(n) / committed) for facet, n in counts.items()), key=lambda r: -r[1])


def lines(summary: Summary) -> list[str]:
    """The CLI's end lines: "412 runs left through v1 < 0 (truncated, counted safe)"
    for each facet with a noticeable share."""
    return [f"{runs} runs left through {facet} (truncated, counted safe; {share:.1%} of committed runs)"
            for facet, runs, share in shares(summary) if share >= NOTICEABLE_SHARE]


def side_lines(summary: Summary) -> list[str]:
    """With sides, the CLI's end lines for the runs of a side's study that reached another
    side's failure facet (a noticeable share): no truncation, but a failure that study
    leaves out; the total's study and that other side's count them as failures."""
    committed = max(summary.runs_committed, 1)
    return [f"{runs} runs of the {side} side's study reached {facet}, another side's failure (not one of the "
            f"{side} side, whose study leaves that facet out; the total counts it; {runs / committed:.1%} of "
            f"committed runs)"
            for facet, by_side in (summary.side_failures or {}).items() for side, runs in by_side.items()
            if runs / committed >= NOTICEABLE_SHARE]
