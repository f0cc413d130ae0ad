"""The command line's grammar: ``scenario-farm COMMAND ...`` (farm/cli/commands.py runs it).
Each command's handler is ``farm.cli.handlers.cmd_<command>``."""

from __future__ import annotations

import argparse

from farm.cli import exits
from scenarios.version import __version__

DESCRIPTION = "scenario-farm (also python -m farm): a thin layer over farm.api."


def _add_farm_flags(p, seed=True):
    p.add_argument("--workers", type=int, help="Ray actors; a local Ray takes at most 4 per CPU, more with "
                                               "farm.waiting (overrides farm.workers)")
    p.add_argument("--address", help="'local' (start Ray here), 'auto' (join the cluster of RAY_ADDRESS or `ray "
                                     "start`), 'host:port' or 'ray://host:port'; one that answers nothing within 3 s "
                                     "is refused (farm.address)")
    p.add_argument("--executor", choices=["ray", "local", "virtual"], help="overrides farm.executor")
    if seed:
        p.add_argument("--seed", type=int, help="campaign seed (overrides farm.seed)")


def _add_output_flags(p) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", action="store_true", help="no progress output (errors and the result only)")
    g.add_argument("--verbose", action="store_true", help="a progress line every 2 s and at every round end")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="scenario-farm", description=DESCRIPTION,
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog=f"exit codes:\n{exits.table_text()}")
    parser.add_argument("--version", action="version", version=f"scenario-farm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("validate", help="certify a claimed safe domain or find a counterexample")
    p.add_argument("config")
    p.add_argument("--json", action="store_true", help="print the certificate as JSON")
    p.add_argument("--out", help="directory for certificate.json (and counterexample.mcap)")
    p.add_argument("--force", action="store_true", help="replace an existing certificate.json")
    p.add_argument("--algorithm", choices=["delta", "eps", "eps-delta"], help="overrides validate.algorithm")
    _add_farm_flags(p)
    _add_output_flags(p)

    p = sub.add_parser("quantify", help="find the maximal safe sub-domain (SPE and baselines)")
    p.add_argument("config")
    p.add_argument("--out", required=True, help="campaign directory")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true", help="continue the campaign in a non-empty --out")
    g.add_argument("--force", action="store_true", help="replace the campaign in --out (only a campaign directory)")
    p.add_argument("--checkpoint-every", type=float, help="seconds between checkpoints, at least 1 "
                                                          "(farm.checkpoint_every)")
    p.add_argument("--max-memory-gb", type=float, help="the memory a campaign may hold, in GB; past it the campaign "
                                                       "stops checkpointed (farm.max_memory_gb)")
    _add_farm_flags(p)
    _add_output_flags(p)

    p = sub.add_parser("plan", help="time to the result at several worker counts, on the virtual farm")
    p.add_argument("config")
    p.add_argument("--out", required=True, help="plan directory: plan.json, plan.png and a campaign per count")
    p.add_argument("--workers", type=int, nargs="+", default=[1, 32, 256], help="worker counts (default 1 32 256)")
    p.add_argument("--run-time", type=float, help="seconds of a full-horizon run of your simulator "
                                                  "(farm.virtual.run_time)")
    p.add_argument("--call-cost", type=float, help="seconds a chunk's call costs (farm.virtual.call_cost)")
    p.add_argument("--jitter", type=float, help="lognormal sigma of a run's time (farm.virtual.jitter)")
    p.add_argument("--seed", type=int, help="campaign seed (overrides farm.seed)")
    p.add_argument("--force", action="store_true", help="replace the plan in --out (only a plan directory)")
    _add_output_flags(p)

    p = sub.add_parser("estimate", help="estimate P(failure) under a scenario distribution D, with an interval, "
                                        "beside a campaign's safe set")
    p.add_argument("dir", help="a finished quantify campaign")
    p.add_argument("--config", help="a TOML file holding an [estimate] table (default: the campaign's)")
    p.add_argument("--runs", type=int, help="stop at this budget of runs (estimate.runs)")
    p.add_argument("--relative-error", type=float, help="stop once the interval's half-width is at most this share "
                                                        "of the estimate (estimate.relative_error)")
    p.add_argument("--confidence", type=float, help="the interval's level (estimate.confidence)")
    p.add_argument("--plain", action="store_true", help="plain Monte Carlo: the set switched off, for comparison "
                                                        "(estimate.strata = 'none')")
    p.add_argument("--versus-sv-policy", help="also run this SV policy on the same runs: the paired difference "
                                              "(estimate.versus.sv_policy)")
    p.add_argument("--versus-scenario", help="also run this scenario ('package.module:Class', another version of "
                                             "your controller) on the same runs (estimate.versus.name)")
    p.add_argument("--name", help="DIR/estimates/<name> (default: stratified, plain, with -vs-<controller>)")
    p.add_argument("--seed", type=int, help="the estimate's seed (estimate.seed; default: derived from farm.seed)")
    p.add_argument("--json", action="store_true", help="print estimate.json")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true", help="continue a stopped or killed estimate (or extend one "
                                                         "with a larger --runs)")
    g.add_argument("--force", action="store_true", help="replace the estimate of that name")
    p.add_argument("--checkpoint-every", type=float, help="seconds between checkpoints, at least 1 "
                                                          "(farm.checkpoint_every)")
    _add_farm_flags(p, seed=False)
    _add_output_flags(p)

    p = sub.add_parser("resume", help="continue a stopped or killed campaign")
    p.add_argument("dir")
    p.add_argument("--checkpoint-every", type=float)
    p.add_argument("--max-memory-gb", type=float, help="the memory a campaign may hold, in GB; past it the campaign "
                                                       "stops checkpointed (farm.max_memory_gb)")
    _add_farm_flags(p, seed=False)
    _add_output_flags(p)

    p = sub.add_parser("report", help="redraw the plots and print the summary of a campaign")
    p.add_argument("dir", nargs="+")
    p.add_argument("--overlay", action="store_true",
                   help="draw the campaigns on the same slices (DIR1/plots/overlay.png), e.g. brake against idm")
    p.add_argument("--html", action="store_true", help="also write DIR/report.html (figures, guarantee, rounds)")
    p.add_argument("--graph", action="store_true",
                   help="also write the exploration graph as GraphML (DIR/exploration_graph.graphml)")
    p.add_argument("--hold", action="append", default=[], metavar="NAME=VALUE",
                   help="hold a state the figures do not show at VALUE (repeatable; default: mid-range), "
                        "e.g. --hold v1=5 --hold p10=20")

    p = sub.add_parser("status", help="report a running or stopped campaign from its files")
    p.add_argument("dir")
    p.add_argument("--watch", action="store_true", help="follow a running campaign until it ends (Ctrl-C stops "
                                                        "watching, not the campaign)")

    p = sub.add_parser("replay", help="re-run one committed run from its stream key and check it")
    p.add_argument("dir")
    p.add_argument("--sample", type=int, required=True, help="global sample index")

    p = sub.add_parser("compare", help="compare a quantified set with the reference safe set")
    p.add_argument("dir")
    p.add_argument("--grid", type=int, default=None, help="reference grid points per axis (default: ~1.5e6 points "
                                                          "for a model reference, 24^3 for a simulated one)")
    p.add_argument("--grid-total", type=int, default=None, help="reference grid points in all (the most points per "
                                                                "axis that fit)")
    p.add_argument("--points", type=int, default=None, help="compare on this many states uniform in Sigma instead "
                                                            "of a grid, with 95%% intervals (default above 5 axes: "
                                                            "200000)")
    p.add_argument("--estimate", action="store_true", help="say how many runs the reference takes and how long "
                                                           "(from a timed first batch), then stop")
    _add_output_flags(p)

    p = sub.add_parser("falsify", help="try the worst case Gamma* a search campaign proposed (adversary.json)")
    p.add_argument("dir")
    p.add_argument("--gamma-star", type=float, nargs="+", help="the actions to try instead of the proposal "
                                                                 "(one number per action)")
    p.add_argument("--points", type=int, default=10_000, help="uniform start states (default 10000)")
    p.add_argument("--tries", type=int, default=4, help="random sequences per Gamma*-safe start (default 4)")
    p.add_argument("--seed", type=int, default=None, help="default: the campaign's farm.seed")
    _add_output_flags(p)

    p = sub.add_parser("export", help="write a campaign's failing runs and certified set for other tools")
    p.add_argument("dir")
    p.add_argument("--xosc", action="store_true", help="as ASAM OpenSCENARIO (.xosc) with OpenDRIVE roads (.xodr), "
                                                       "into DIR/openscenario/")
    p.add_argument("--force", action="store_true", help="replace an earlier export in DIR/openscenario/")

    p = sub.add_parser("schema", help="print the JSON Schema of the config (for editors)")
    return parser
