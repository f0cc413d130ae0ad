"""The CLI's commands, one handler each: ``cmd_<command>(args) -> exit code``, a thin
layer over ``farm.api`` (farm/cli/commands.py loads this module once its signal
handlers and error lines are in place)."""

from __future__ import annotations

import json
from pathlib import Path

from farm import api, config as config_mod, lazy
from farm.cli import exits
from farm.directory.storage import CampaignDir
from farm.jobs import quantification
from farm.reports import status
from farm.reports.estimate_report import EstimateReport, describe as describe_estimate, estimate_dirs
from farm.reports.progress import Progress
from farm.reports.summary import Summary, budget_used_up
from farm.reports.holdout import describe_holdout
from farm.reports.truncations import lines as truncation_lines
from farm.reports.truncations import side_lines
from scenarios.errors import ConfigError, ScenarioError

EXIT_OK, EXIT_COUNTEREXAMPLE = exits.OK, exits.FINDING


def _overrides(args) -> dict:
    return {f"farm.{k}": getattr(args, k, None) for k in ("workers", "address", "executor", "seed",
                                                           "checkpoint_every", "max_memory_gb")}


def cmd_validate(args) -> int:
    overrides = _farm_kwargs(args)
    if args.algorithm:
        overrides["validate__algorithm"] = args.algorithm

    progress = Progress(mode=_mode(args))
    cert = api.validate(args.config, out=args.out, force=args.force,
                        progress=lambda done, total: progress.count("validation runs", done, total), **overrides)
    print(json.dumps(cert.data, indent=2) if args.json else f"{cert.guarantee}\nFormally: {cert.statement}")
    return EXIT_OK if cert.certified else EXIT_COUNTEREXAMPLE


def _farm_kwargs(args) -> dict:
    return {k.replace(".", "__"): v for k, v in _overrides(args).items() if v is not None}


def _mode(args) -> str:
    return "quiet" if getattr(args, "quiet", False) else "verbose" if getattr(args, "verbose", False) else "auto"


def cmd_quantify(args) -> int:
    text = config_mod.read_text(args.config)  # once: the config may be a stream, <(cat c.toml)
    cfg = config_mod.parse(text, args.config).with_overrides(_overrides(args))
    quantification.run(cfg, Path(args.out), resume=args.resume, force=args.force,
                       progress=Progress(mode=_mode(args)), config_text=text)
    _print_summary(Path(args.out))
    return EXIT_OK


def cmd_estimate(args) -> int:
    overrides = {f"estimate__{k}": getattr(args, k) for k in ("runs", "relative_error", "confidence", "seed")
                 if getattr(args, k) is not None}
    overrides.update({f"farm__{k}": getattr(args, k) for k in ("workers", "address", "executor", "checkpoint_every")
                      if getattr(args, k) is not None})
    if args.plain:
        overrides["estimate__strata"] = "none"
    versus = {k: v for k, v in (("sv_policy", args.versus_sv_policy), ("name", args.versus_scenario)) if v}
    if versus:
        overrides["estimate__versus"] = versus
    report = api.estimate(args.dir, args.config, name=args.name, resume=args.resume, force=args.force,
                          progress=Progress(mode=_mode(args)), **overrides)
    if args.json:
        print(json.dumps(report.to_json(), indent=2))
    else:
        _print_estimate(report)
    return EXIT_OK


def _print_estimates(campaign: Path) -> None:
    """A line per estimate of the campaign (DIR/estimates/*/estimate.json), with its detail."""
    for folder in estimate_dirs(campaign):
        _print_estimate(EstimateReport.read(folder))


def _print_estimate(report: EstimateReport) -> None:
    first, *rest = describe_estimate(report)
    print(f"{'failure rate':>18}: {first}")
    for line in rest:
        print(f"{'':>18}  {line.strip()}")


def cmd_plan(args) -> int:
    result = api.plan(args.config, out=args.out, workers=args.workers, force=args.force, run_time=args.run_time,
                      call_cost=args.call_cost, jitter=args.jitter, progress=_mode(args) != "quiet",
                      **({"farm__seed": args.seed} if args.seed is not None else {}))
    print(lazy.planning.table(result))
    print(f"written: {Path(args.out) / 'plan.json'}, {Path(args.out) / 'plan.png'}, a campaign per count in "
          f"{Path(args.out) / 'workers-<W>'}")
    return EXIT_OK if result["same_result"] else exits.BUG  # the worker count never changes a result


def cmd_resume(args) -> int:
    out = Path(args.dir)
    CampaignDir(out).open("quantify")
    cfg = CampaignDir(out).frozen_config().with_overrides(_overrides(args))
    done = Summary.finished(out)
    if done is not None and not quantification.finishing_interrupted(out):
        print(f"{out}: the campaign has finished (result hash {done['result_hash']}); nothing to resume")
        return EXIT_OK
    quantification.run(cfg, out, resume=True, progress=Progress(mode=_mode(args)))
    _print_summary(out)
    return EXIT_OK


def _print_summary(out: Path, summary=None) -> None:
    """The main figures of the campaign in ``out`` (its summary.json, or ``summary``)."""
    summary = summary or Summary.read(out)
    keys = ["scenario", "sv_policy", "algorithm", "delta_final", "half_width_max", "rounds", "boxes", "volume_union", "volume_hull",
            "runs_committed", "runs_certification", "certification_attempts", "certification_check_violations",
            "runs_simulated", "steps_simulated",
            "elapsed_s", "startup_s", "result_hash"]
    values = summary.to_json()
    for k in keys + [k for k in values if k.startswith("volume_") and k.endswith("_side")]:
        if k in ("runs_certification", "certification_attempts", "certification_check_violations") \
                and not values.get(k):
            continue  # no certification (or a passing check that saw no violation)
        if k in values and not (k == "half_width_max" and values[k] == values.get("delta_final")):
            v = values[k]
            print(f"{k:>18}: {v:.6g}" if isinstance(v, float) else f"{k:>18}: {v}")

    for line in truncation_lines(summary):
        print(f"{'truncated':>18}: {line}")
    for line in side_lines(summary):
        print(f"{'side study':>18}: {line}")
    if summary.holdout:
        print(f"{'holdout':>18}: {describe_holdout(summary.holdout)}")
    if not summary.converged:
        budget = CampaignDir(out).frozen_config().quantify.budget
        print(f"{'budget':>18}: {budget_used_up(budget, summary.runs_committed, summary.runs_simulated)}")
    print(f"{'guarantee':>18}: {summary.guarantee}")
    if summary.guarantee_formal:
        print(f"{'formally':>18}: {summary.guarantee_formal}")
    print(f"{'results':>18}: {out}/summary.json, {out}/safe_set.parquet, {out}/plots/")


def parse_hold(items: list[str]) -> dict[str, float]:
    """``["v1=5", "p10=20"]`` -> {"v1": 5.0, "p10": 20.0}; ConfigError on another form."""
    hold = {}
    for item in items:
        name, sep, value = item.partition("=")
        try:
            hold[name.strip()] = float(value)
        except ValueError:
            sep = ""
        if not sep or not name.strip():
            raise ConfigError(f"report --hold: {item!r} is not NAME=VALUE (a state name and a number, e.g. v1=5)")
    return hold


def cmd_report(args) -> int:
    if args.overlay:
        if len(args.dir) < 2:
            raise ConfigError("report --overlay: give two or more campaign directories")
        path = api.overlay(args.dir, Path(args.dir[0]) / "plots" / "overlay.png")
        print(f"{'overlay':>18}: {path}")
        return EXIT_OK
    hold = parse_hold(args.hold)
    for directory in args.dir:
        result = api.open_campaign(directory)
        try:
            paths = result.plot(hold=hold)
        except ValueError as exc:  # an axis the scenario has not, or a value outside Sigma
            raise ConfigError(f"report --{exc}") from None
        failures = result.plot_failures()
        _print_summary(Path(directory), result.summary)
        _print_estimates(Path(directory))
        print(f"{'plots':>18}: {', '.join(str(p) for p in paths + ([failures] if failures else []))}")
        if args.graph:
            print(f"{'graph':>18}: {result.export_graph()}")
        if args.html:
            print(f"{'report':>18}: {result.report_html()}")
    return EXIT_OK


def cmd_status(args) -> int:
    if args.watch:
        try:
            status.watch(Path(args.dir))
        except KeyboardInterrupt:
            pass  # Ctrl-C ends the watch, not the campaign
        return EXIT_OK
    print(status.describe(Path(args.dir)))
    return EXIT_OK


def cmd_replay(args) -> int:
    ok, finding, text = lazy.rerun.replay(Path(args.dir), args.sample)
    print(text)
    if not ok:
        raise ScenarioError(f"{args.dir}: the replay of sample {args.sample} does not match the record (the DIFF "
                            f"lines above): a scenario whose runs are not fixed by their stream key, or changed files")
    return EXIT_COUNTEREXAMPLE if finding else EXIT_OK  # a reproduced counterexample is a finding


def cmd_compare(args) -> int:
    progress = Progress(mode=_mode(args))
    if args.estimate:

        plan = api.compare(args.dir, grid=args.grid, grid_total=args.grid_total, estimate_only=True, progress=progress,
                           points=args.points)
        print(lazy.compare.describe_estimate(Path(args.dir), plan))
        return EXIT_OK
    metrics = api.compare(args.dir, grid=args.grid, grid_total=args.grid_total, progress=progress, points=args.points)
    print(lazy.compare.describe(Path(args.dir), metrics))
    return EXIT_OK


def cmd_falsify(args) -> int:
    report = api.falsify(args.dir, gamma_star=args.gamma_star, points=args.points, tries=args.tries, seed=args.seed,
                         progress=Progress(mode=_mode(args)))
    print(lazy.falsify.describe(Path(args.dir), report))
    return EXIT_COUNTEREXAMPLE if report["refuted"] else EXIT_OK


def cmd_export(args) -> int:
    if not args.xosc:
        raise ConfigError("export: choose a format; allowed: --xosc (ASAM OpenSCENARIO and OpenDRIVE)")
    print(lazy.openscenario.describe(api.export_openscenario(args.dir, force=args.force)))
    return EXIT_OK


def cmd_schema(args) -> int:
    print(json.dumps(config_mod.schema(), indent=2))
    return EXIT_OK
