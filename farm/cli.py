"""``scenario-farm`` (also ``python -m farm``): validate, quantify, resume, report,
status, replay, compare.

Exit codes: 0 success (certified, campaign finished), 1 counterexample found,
2 bad input (one line naming the field and the allowed range; nothing touched),
3 a failure while running (a scenario raised, workers died beyond the retry bound).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from farm import __version__

EXIT_OK, EXIT_COUNTEREXAMPLE, EXIT_BAD_INPUT, EXIT_RUNTIME = 0, 1, 2, 3


def _farm_overrides(args) -> dict:
    return {"farm.workers": getattr(args, "workers", None), "farm.address": getattr(args, "address", None),
            "farm.executor": getattr(args, "executor", None), "farm.seed": getattr(args, "seed", None),
            "farm.checkpoint_every": getattr(args, "checkpoint_every", None)}


def _add_farm_flags(p, seed=True):
    p.add_argument("--workers", type=int, help="Ray actors (overrides farm.workers)")
    p.add_argument("--address", help="'local' (start Ray here) or 'auto' (join the cluster) (farm.address)")
    p.add_argument("--executor", choices=["ray", "local"], help="overrides farm.executor")
    if seed:
        p.add_argument("--seed", type=int, help="campaign seed (overrides farm.seed)")


def cmd_validate(args) -> int:
    from coordinator.domain import Domain
    from farm.files import write_json
    from coordinator.validation import plan, validate, verdict_sentence
    from farm import config as config_mod
    from farm.executors import SimSpec, build_simulator
    from farm.ray_executor import make_executor

    cfg = config_mod.load(args.config, _farm_overrides(args))
    v, farm = cfg["validate"], cfg["farm"]
    spec = SimSpec(dict(cfg["scenario"]), dict(cfg["actions"]), v["horizon"], farm["seed"])
    scenario, policy = build_simulator(spec)
    domain = Domain.from_config(scenario, v)
    deterministic = policy.deterministic and scenario.disturbance == 0
    p = plan(domain, v["algorithm"], v["epsilon"], v["beta"], v["delta"], v["boundary"], deterministic)
    out = Path(args.out) if args.out else None
    if out is not None and (out / "certificate.json").exists() and not args.force:
        raise FileExistsError(f"{out}/certificate.json exists; pass --force to replace it")
    executor = make_executor(farm["executor"], spec, farm["workers"], farm["address"], farm["max_retries"])
    try:
        result = validate(domain, p, executor, seed=farm["seed"], delta=v["delta"], batch_size=farm["batch_size"],
                          pipeline_depth=farm["pipeline_depth"])
    finally:
        executor.close()
    sentence = verdict_sentence(result, p, epsilon=v["epsilon"], beta=v["beta"], delta=v["delta"],
                                seed=farm["seed"], action_description=policy.description,
                                adversarial=cfg["actions"]["mode"] == "adversarial")
    cert = {"verdict": result["verdict"], "statement": sentence, "algorithm": p.algorithm,
            "epsilon": v["epsilon"], "beta": v["beta"], "delta": v["delta"], "n_required": p.n_required,
            "n_run": result["n_run"], "runs_simulated": result["runs_simulated"],
            "steps_simulated": result["steps_simulated"], "seed": farm["seed"],
            "config_hash": config_mod.config_hash(cfg), "scenario": cfg["scenario"]["name"],
            "sv_policy": cfg["scenario"]["sv_policy"], "domain": domain.describe(), "sampling": p.description,
            "actions": policy.description, "boundary": v["boundary"],
            "counterexample": result["counterexample"], "scenario_farm_version": __version__}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "config.json", {"config": cfg, "config_hash": cert["config_hash"]})
        write_json(out / "certificate.json", cert)
        if result["counterexample"] and cfg["record"]["counterexamples"]:
            from farm.replay import record_counterexample

            record_counterexample(out / "counterexample.mcap", scenario, cert)
    if args.json:
        print(json.dumps(cert, indent=2))
    else:
        print(sentence)
    return EXIT_OK if result["verdict"] == "certified" else EXIT_COUNTEREXAMPLE


def cmd_quantify(args) -> int:
    from farm import config as config_mod
    from farm import quantify
    from farm.progress import Progress

    cfg = config_mod.load(args.config, _farm_overrides(args))
    out = Path(args.out)
    resuming = quantify.prepare_directory(out, Path(args.config), cfg, resume=args.resume, force=args.force)
    if resuming:
        quantify.check_resume_config(out, cfg)
    summary = quantify.run(cfg, out, resume=resuming, progress=Progress())
    _print_summary(summary, out)
    return EXIT_OK


def cmd_resume(args) -> int:
    from farm import config as config_mod
    from farm import quantify
    from farm.progress import Progress

    out = Path(args.dir)
    cfg = quantify.load_frozen_config(out)
    for dotted, value in _farm_overrides(args).items():
        if value is not None:
            section, key = dotted.split(".")
            cfg[section][key] = config_mod.SCHEMA[section][key].check(f"--{key}", value)
    summary = quantify.run(cfg, out, resume=True, progress=Progress())
    _print_summary(summary, out)
    return EXIT_OK


def _print_summary(summary: dict, out: Path) -> None:
    keys = ["scenario", "sv_policy", "algorithm", "delta_final", "rounds", "boxes", "volume_union", "volume_hull",
            "runs_committed", "runs_simulated", "steps_simulated", "elapsed_s", "result_hash"]
    for k in keys + [k for k in summary if k.startswith("volume_") and k.endswith("_side")]:
        if k in summary:
            v = summary[k]
            print(f"{k:>18}: {v:.6g}" if isinstance(v, float) else f"{k:>18}: {v}")
    print(f"{'guarantee':>18}: {summary['guarantee']}")
    print(f"{'results':>18}: {out}/summary.json, {out}/safe_set.parquet, {out}/plots/")


def cmd_report(args) -> int:
    from farm.plots import draw
    from farm.files import read_safe_set
    from farm import quantify
    from farm.executors import build_simulator

    out = Path(args.dir)
    try:
        summary = json.loads((out / "summary.json").read_text())
    except FileNotFoundError:
        raise ValueError(f"{out}: no summary.json (is the campaign finished? try `scenario-farm status {out}`)") from None
    cfg = quantify.load_frozen_config(out)
    scenario, _ = build_simulator(quantify.spec_of(cfg))
    centres, h = read_safe_set(out / "safe_set.parquet", scenario.state_names)
    paths = draw(out / "plots", scenario, centres, h, summary)
    _print_summary(summary, out)
    print(f"{'plots':>18}: {', '.join(str(p) for p in paths)}")
    return EXIT_OK


def cmd_status(args) -> int:
    from farm.status import describe

    print(describe(Path(args.dir)))
    return EXIT_OK


def cmd_replay(args) -> int:
    from farm.replay import replay

    ok, text = replay(Path(args.dir), args.sample)
    print(text)
    return EXIT_OK if ok else EXIT_COUNTEREXAMPLE


def cmd_compare(args) -> int:
    from farm.compare import compare

    print(compare(Path(args.dir), grid=args.grid))
    return EXIT_OK


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="scenario-farm", description=__doc__.split("\n\n")[0])
    parser.add_argument("--version", action="version", version=f"scenario-farm {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)

    p = sub.add_parser("validate", help="certify a claimed safe domain or find a counterexample")
    p.add_argument("config")
    p.add_argument("--json", action="store_true", help="print the certificate as JSON")
    p.add_argument("--out", help="directory for certificate.json (and counterexample.mcap)")
    p.add_argument("--force", action="store_true", help="replace an existing certificate.json")
    _add_farm_flags(p)
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("quantify", help="find the maximal safe sub-domain (SPE and baselines)")
    p.add_argument("config")
    p.add_argument("--out", required=True, help="campaign directory")
    g = p.add_mutually_exclusive_group()
    g.add_argument("--resume", action="store_true", help="continue the campaign in a non-empty --out")
    g.add_argument("--force", action="store_true", help="replace the campaign in a non-empty --out")
    p.add_argument("--checkpoint-every", type=float, help="seconds between checkpoints (farm.checkpoint_every)")
    _add_farm_flags(p)
    p.set_defaults(func=cmd_quantify)

    p = sub.add_parser("resume", help="continue a stopped or killed campaign")
    p.add_argument("dir")
    p.add_argument("--checkpoint-every", type=float)
    _add_farm_flags(p, seed=False)
    p.set_defaults(func=cmd_resume)

    p = sub.add_parser("report", help="redraw the plots and print the summary of a campaign")
    p.add_argument("dir")
    p.set_defaults(func=cmd_report)

    p = sub.add_parser("status", help="report a running or stopped campaign from its files")
    p.add_argument("dir")
    p.set_defaults(func=cmd_status)

    p = sub.add_parser("replay", help="re-run one committed run from its stream key and check it")
    p.add_argument("dir")
    p.add_argument("--sample", type=int, required=True, help="global sample index")
    p.set_defaults(func=cmd_replay)

    p = sub.add_parser("compare", help="compare a quantified set with the model-based reference")
    p.add_argument("dir")
    p.add_argument("--grid", type=int, default=None, help="reference grid points per axis")
    p.set_defaults(func=cmd_compare)
    return parser


def main(argv=None) -> int:
    from coordinator.domain import DomainError
    from farm.config import ConfigError
    from farm.memory import keep_freed_memory
    from farm.storage import CampaignError

    parser = build_parser()
    args = parser.parse_args(argv)
    keep_freed_memory()  # the coordinator's batch queries allocate like a simulator's steps
    try:
        return args.func(args)
    except (ConfigError, DomainError, CampaignError, FileExistsError) as exc:
        print(f"scenario-farm: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        print("scenario-farm: stopped; the campaign was checkpointed (continue with `scenario-farm resume DIR`)",
              file=sys.stderr)
        return 130
    except ValueError as exc:  # raised by scenario/back-end constructors on bad config values
        print(f"scenario-farm: error: {exc}", file=sys.stderr)
        return EXIT_BAD_INPUT
    except RuntimeError as exc:  # ScenarioError, WorkerError, EmptySetError
        print(f"scenario-farm: error: {exc}", file=sys.stderr)
        return EXIT_RUNTIME
