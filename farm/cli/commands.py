"""``scenario-farm`` (also ``python -m farm``): a thin layer over ``farm.api``.

Every error ends as one line on stderr and an exit code (farm/cli/exits.py: the table and the
lines); ``SCENARIO_FARM_DEBUG=1`` also prints the traceback, and keeps Ray's own log lines.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import stat
import sys
import warnings
from pathlib import Path
from typing import NoReturn

from farm.cli import exits
from scenarios.errors import ConfigError
from scenarios.version import __version__

EXIT_OK, EXIT_COUNTEREXAMPLE = exits.OK, exits.FINDING


def _overrides(args) -> dict:
    return {f"farm.{k}": getattr(args, k, None) for k in ("workers", "address", "executor", "seed",
                                                           "checkpoint_every")}


def _add_farm_flags(p, seed=True):
    p.add_argument("--workers", type=int, help="Ray actors; a local Ray takes at most 4 per CPU (overrides "
                                               "farm.workers)")
    p.add_argument("--address", help="'local' (start Ray here), 'auto' (join the cluster of RAY_ADDRESS or `ray "
                                     "start`), 'host:port' or 'ray://host:port'; one that answers nothing within 3 s "
                                     "is refused (farm.address)")
    p.add_argument("--executor", choices=["ray", "local", "virtual"], help="overrides farm.executor")
    if seed:
        p.add_argument("--seed", type=int, help="campaign seed (overrides farm.seed)")


def cmd_validate(args) -> int:
    from farm import api

    overrides = _farm_kwargs(args)
    if args.algorithm:
        overrides["validate__algorithm"] = args.algorithm
    from farm.reports.progress import Progress

    progress = Progress(mode=_mode(args))
    cert = api.validate(args.config, out=args.out, force=args.force,
                        progress=lambda done, total: progress.count("validation runs", done, total), **overrides)
    print(json.dumps(cert.data, indent=2) if args.json else f"{cert.guarantee}\nFormally: {cert.statement}")
    return EXIT_OK if cert.certified else EXIT_COUNTEREXAMPLE


def _farm_kwargs(args) -> dict:
    return {k.replace(".", "__"): v for k, v in _overrides(args).items() if v is not None}


def _mode(args) -> str:
    return "quiet" if getattr(args, "quiet", False) else "verbose" if getattr(args, "verbose", False) else "auto"


def _add_output_flags(p) -> None:
    g = p.add_mutually_exclusive_group()
    g.add_argument("--quiet", action="store_true", help="no progress output (errors and the result only)")
    g.add_argument("--verbose", action="store_true", help="a progress line every 2 s and at every round end")


def cmd_quantify(args) -> int:
    from farm import config as config_mod
    from farm.jobs import quantification
    from farm.reports.progress import Progress

    text = config_mod.read_text(args.config)  # once: the config may be a stream, <(cat c.toml)
    cfg = config_mod.parse(text, args.config).with_overrides(_overrides(args))
    quantification.run(cfg, Path(args.out), resume=args.resume, force=args.force,
                       progress=Progress(mode=_mode(args)), config_text=text)
    _print_summary(Path(args.out))
    return EXIT_OK


def cmd_plan(args) -> int:
    from farm import api
    from farm.jobs.planning import table

    result = api.plan(args.config, out=args.out, workers=args.workers, force=args.force, run_time=args.run_time,
                      call_cost=args.call_cost, jitter=args.jitter, progress=_mode(args) != "quiet",
                      **({"farm__seed": args.seed} if args.seed is not None else {}))
    print(table(result))
    print(f"written: {Path(args.out) / 'plan.json'}, {Path(args.out) / 'plan.png'}, a campaign per count in "
          f"{Path(args.out) / 'workers-<W>'}")
    return EXIT_OK if result["same_result"] else exits.BUG  # the worker count never changes a result


def cmd_resume(args) -> int:
    from farm.jobs import quantification
    from farm.reports.progress import Progress
    from farm.directory.storage import CampaignDir

    out = Path(args.dir)
    CampaignDir(out).open("quantify")
    cfg = CampaignDir(out).frozen_config().with_overrides(_overrides(args))
    done = CampaignDir(out).finished_summary()
    if done is not None:
        print(f"{out}: the campaign has finished (result hash {done['result_hash']}); nothing to resume")
        return EXIT_OK
    quantification.run(cfg, out, resume=True, progress=Progress(mode=_mode(args)))
    _print_summary(out)
    return EXIT_OK


def _print_summary(out: Path, summary=None) -> None:
    """The main figures of the campaign in ``out`` (its summary.json, or ``summary``)."""
    from farm.reports.summary import Summary

    summary = summary or Summary.read(out)
    keys = ["scenario", "sv_policy", "algorithm", "delta_final", "half_width_max", "rounds", "boxes", "volume_union", "volume_hull",
            "runs_committed", "runs_certification", "certification_attempts", "runs_simulated", "steps_simulated",
            "elapsed_s", "startup_s", "result_hash"]
    values = summary.to_json()
    for k in keys + [k for k in values if k.startswith("volume_") and k.endswith("_side")]:
        if k in ("runs_certification", "certification_attempts") and not values.get(k):
            continue  # no certification
        if k in values and not (k == "half_width_max" and values[k] == values.get("delta_final")):
            v = values[k]
            print(f"{k:>18}: {v:.6g}" if isinstance(v, float) else f"{k:>18}: {v}")
    from farm.reports.truncations import lines

    for line in lines(summary):
        print(f"{'truncated':>18}: {line}")
    print(f"{'guarantee':>18}: {summary.guarantee}")
    if summary.guarantee_formal:
        print(f"{'formally':>18}: {summary.guarantee_formal}")
    print(f"{'results':>18}: {out}/summary.json, {out}/safe_set.parquet, {out}/plots/")


def cmd_report(args) -> int:
    from farm import api

    if args.overlay:
        if len(args.dir) < 2:
            raise ConfigError("report --overlay: give two or more campaign directories")
        path = api.overlay(args.dir, Path(args.dir[0]) / "plots" / "overlay.png")
        print(f"{'overlay':>18}: {path}")
        return EXIT_OK
    for directory in args.dir:
        result = api.open_campaign(directory)
        paths = result.plot()
        failures = result.plot_failures()
        _print_summary(Path(directory), result.summary)
        print(f"{'plots':>18}: {', '.join(str(p) for p in paths + ([failures] if failures else []))}")
        if args.graph:
            print(f"{'graph':>18}: {result.export_graph()}")
        if args.html:
            print(f"{'report':>18}: {result.report_html()}")
    return EXIT_OK


def cmd_status(args) -> int:
    from farm.reports.status import describe, watch

    if args.watch:
        try:
            watch(Path(args.dir))
        except KeyboardInterrupt:
            pass  # Ctrl-C ends the watch, not the campaign
        return EXIT_OK
    print(describe(Path(args.dir)))
    return EXIT_OK


def cmd_replay(args) -> int:
    from farm.jobs.rerun import replay

    ok, text = replay(Path(args.dir), args.sample)
    print(text)
    return EXIT_OK if ok else EXIT_COUNTEREXAMPLE


def cmd_compare(args) -> int:
    from farm import api
    from farm.reports.compare import describe

    from farm.reports.progress import Progress

    progress = Progress(mode=_mode(args))
    if args.estimate:
        from farm.reports.compare import describe_estimate

        plan = api.compare(args.dir, grid=args.grid, grid_total=args.grid_total, estimate_only=True, progress=progress)
        print(describe_estimate(Path(args.dir), plan))
        return EXIT_OK
    metrics = api.compare(args.dir, grid=args.grid, grid_total=args.grid_total, progress=progress)
    print(describe(Path(args.dir), metrics))
    return EXIT_OK


def cmd_falsify(args) -> int:
    from farm import api
    from farm.jobs.falsify import describe
    from farm.reports.progress import Progress

    report = api.falsify(args.dir, gamma_star=args.gamma_star, points=args.points, tries=args.tries, seed=args.seed,
                         progress=Progress(mode=_mode(args)))
    print(describe(Path(args.dir), report))
    return EXIT_COUNTEREXAMPLE if report["refuted"] else EXIT_OK


def cmd_export(args) -> int:
    from farm import api
    from farm.openscenario.export import describe

    if not args.xosc:
        raise ConfigError("export: choose a format; allowed: --xosc (ASAM OpenSCENARIO and OpenDRIVE)")
    print(describe(api.export_openscenario(args.dir, force=args.force)))
    return EXIT_OK


def cmd_schema(args) -> int:
    from farm.config import schema

    print(json.dumps(schema(), indent=2))
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="scenario-farm", description=__doc__.split("\n\n")[0],
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
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("quantify", help="find the maximal safe sub-domain (SPE and baselines)")
    p.add_argument("config")
    p.add_argument("--out", required=True, help="campaign directory")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true", help="continue the campaign in a non-empty --out")
    g.add_argument("--force", action="store_true", help="replace the campaign in --out (only a campaign directory)")
    p.add_argument("--checkpoint-every", type=float, help="seconds between checkpoints, at least 1 "
                                                          "(farm.checkpoint_every)")
    _add_farm_flags(p)
    _add_output_flags(p)
    p.set_defaults(func=cmd_quantify)

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
    p.set_defaults(func=cmd_plan)

    p = sub.add_parser("resume", help="continue a stopped or killed campaign")
    p.add_argument("dir")
    p.add_argument("--checkpoint-every", type=float)
    _add_farm_flags(p, seed=False)
    _add_output_flags(p)
    p.set_defaults(func=cmd_resume)

    p = sub.add_parser("report", help="redraw the plots and print the summary of a campaign")
    p.add_argument("dir", nargs="+")
    p.add_argument("--overlay", action="store_true",
                   help="draw the campaigns on the same slices (DIR1/plots/overlay.png), e.g. brake against idm")
    p.add_argument("--html", action="store_true", help="also write DIR/report.html (figures, guarantee, rounds)")
    p.add_argument("--graph", action="store_true",
                   help="also write the exploration graph as GraphML (DIR/exploration_graph.graphml)")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("status", help="report a running or stopped campaign from its files")
    p.add_argument("dir")
    p.add_argument("--watch", action="store_true", help="follow a running campaign until it ends (Ctrl-C stops "
                                                        "watching, not the campaign)")
    p.set_defaults(func=cmd_status)

    p = sub.add_parser("replay", help="re-run one committed run from its stream key and check it")
    p.add_argument("dir")
    p.add_argument("--sample", type=int, required=True, help="global sample index")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("compare", help="compare a quantified set with the reference safe set")
    p.add_argument("dir")
    p.add_argument("--grid", type=int, default=None, help="reference grid points per axis (default: ~1.5e6 points "
                                                          "for a model reference, 24^3 for a simulated one)")
    p.add_argument("--grid-total", type=int, default=None, help="reference grid points in all (the most points per "
                                                                "axis that fit)")
    p.add_argument("--estimate", action="store_true", help="say how many runs the reference takes and how long "
                                                           "(from a timed first batch), then stop")
    _add_output_flags(p)
    p.set_defaults(func=cmd_compare)

    p = sub.add_parser("falsify", help="try the worst case Gamma* a search campaign proposed (adversary.json)")
    p.add_argument("dir")
    p.add_argument("--gamma-star", type=float, nargs="+", help="the actions to try instead of the proposal "
                                                                 "(one number per action)")
    p.add_argument("--points", type=int, default=10_000, help="uniform start states (default 10000)")
    p.add_argument("--tries", type=int, default=4, help="random sequences per Gamma*-safe start (default 4)")
    p.add_argument("--seed", type=int, default=None, help="default: the campaign's farm.seed")
    _add_output_flags(p)
    p.set_defaults(func=cmd_falsify)

    p = sub.add_parser("export", help="write a campaign's failing runs and certified set for other tools")
    p.add_argument("dir")
    p.add_argument("--xosc", action="store_true", help="as ASAM OpenSCENARIO (.xosc) with OpenDRIVE roads (.xodr), "
                                                       "into DIR/openscenario/")
    p.add_argument("--force", action="store_true", help="replace an earlier export in DIR/openscenario/")
    p.set_defaults(func=cmd_export)

    p = sub.add_parser("schema", help="print the JSON Schema of the config (for editors)")
    p.set_defaults(func=cmd_schema)
    return parser


def run() -> NoReturn:
    """The ``scenario-farm`` command (and ``python -m farm``): ``main`` on the command
    line's arguments, then the process ends with its exit code (farm/ray_runtime/session.py
    ``exit_process``: at once after a private local Ray)."""
    from farm.ray_runtime.session import exit_process

    exit_process(main())


def main(argv=None) -> int:
    # SIGTERM outside a campaign's own handler (start-up, finishing) ends like Ctrl-C: the
    # files stay as the last checkpoint left them, and the exit says "stopped"
    signal.signal(signal.SIGTERM, _terminate)
    try:
        return _main(argv)
    except KeyboardInterrupt:  # before a command ran
        return exits.interrupted()


def _main(argv) -> int:
    from farm.execution.memory import keep_freed_memory

    parser = build_parser()
    args = parser.parse_args(argv)
    if not os.environ.get(exits.DEBUG):
        from farm.cli.native_stderr import install

        install()  # Ray's C++ log lines stay in its session's log files
    warnings.showwarning = _one_line_warning
    from farm.ray_runtime import watch as ray_watch

    ray_watch.on_lost = lambda why: exits.lost(why, _campaign_dir(args))
    # like `python -m`: 'module:Class' in a config imports from the working directory
    if os.getcwd() not in sys.path:
        sys.path.insert(0, os.getcwd())
    keep_freed_memory()  # the coordinator's batch queries allocate like a simulator's steps
    try:
        return args.func(args)
    except BrokenPipeError as exc:
        if _stdout_closed():  # the reader went away (`scenario-farm status DIR | head -1`): nothing to say
            return EXIT_OK
        return exits.report(exc, _campaign_dir(args))
    except Exception as exc:  # noqa: BLE001 - the one place where errors become exit codes
        return exits.report(exc, _campaign_dir(args))
    except KeyboardInterrupt:
        return exits.interrupted(_campaign_dir(args))


def _stdout_closed() -> bool:
    """Whether the broken pipe is stdout's (its reader went away); if so stdout is pointed
    at /dev/null, so that the interpreter's final flush does not fail again."""
    try:
        if not stat.S_ISFIFO(os.fstat(sys.stdout.fileno()).st_mode):
            return False
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return True
    except (OSError, ValueError):
        return False


def _terminate(signum, frame):
    raise KeyboardInterrupt


def _one_line_warning(message, category, filename, lineno, file=None, line=None):
    print(f"scenario-farm: warning: {' '.join(str(message).split())}", file=sys.stderr)


def _campaign_dir(args) -> str | None:
    """The campaign directory a command works in, for "resume DIR" hints."""
    if args.command == "quantify":
        return args.out
    return args.dir if args.command == "resume" else None
