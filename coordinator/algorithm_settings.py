"""The quantification algorithms' settings, declared once: each with its default, its
allowed values and what it means. The config's [quantify] section is generated from
them (farm/config/sections.py), so a setting's name, range and default have one home."""

from __future__ import annotations

from dataclasses import dataclass, field, fields


def setting(default, doc: str, *, choices: tuple | None = None, hashed_when_default: bool = True, **bounds):
    """A setting's ``default``, its meaning (``doc``), its allowed values (``choices``, or
    ``bounds``: gt / ge / lt / le) and whether the config hash leaves it out at its default
    (a setting added later: configs written before it keep their hashes)."""
    return field(default=default, metadata={"doc": doc, "choices": choices, "bounds": bounds,
                                            "hashed_when_default": hashed_when_default})


@dataclass(frozen=True)
class SPESettings:
    """The parameters of SPE (paper Alg. 8) and of the baselines, which share the rounds."""

    delta0: float = setting(2.0, "delta of the first round: the boxes' initial half-width", gt=0.0)
    gamma: float = setting(0.5, "delta's factor from one round to the next", gt=0.0, lt=1.0)
    delta_min: float = setting(0.5, "delta of the last round: the finest half-width", gt=0.0)
    prioritized: bool = setting(True, "draw starts with probability alpha(d* - d_i), d_i the distance to the "
                                      "failures found (paper Sec. 4.4)")
    alpha: str = setting("identity", "the class-K function of prioritized sampling",
                         choices=("identity", "square", "sqrt"))
    replay: bool = setting(True, "experience replay: stored runs are screened again at each round end")
    replay_capacity: int = setting(20_000_000, (
        "visited states kept for experience replay, duplicates included: the bound on the replay buffer's "
        "memory, n * 8 bytes per state where the states are held (the workers, or the process with the local "
        "executor) and ~50 bytes per kept run on the coordinator; runs of the final round are not kept"),
        ge=0, le=10**10)
    reachable: str = setting("undirected", "which vertices a failure prunes: every vertex connected to the "
                                           "failing start, or its ancestors", choices=("undirected", "ancestors"))
    boundary: bool = setting(False, "draw starts only within sigma-bar of the set's boundary (Theorem 3's "
                                    "boundary set)")
    refine: str = setting("auto", (
        "which boxes a round end splits (spe): all of them; only those within sigma-bar + delta of the set's "
        "failure-side boundary (band: Theorem 3, the others keep their size); or, for a deterministic system, "
        "only those its runs' margins say the boundary crosses, along only the axes it crosses (margin: a "
        "partition of boxes with a half-width per axis, docs/margin_refinement.md). auto: margin for a deterministic "
        "system (one adversarial action, no disturbance), all otherwise"), choices=("auto", "margin", "band", "all"),
        hashed_when_default=False)

    @classmethod
    def names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))
