"""The figures of docs/figures/ (the paper's message, drawn from real campaigns), and
docs/figures.md, rendered from the campaigns' summaries (docs/figures/figures.json).

    python experiments/figures.py              # ~1.5 min on 2 cores; campaigns in runs/figures/
    python experiments/figures.py --render     # docs/figures.md from docs/figures/figures.json only

Every figure comes from the public CLI (the commands are printed as they run and listed
in docs/figures.md): quantification campaigns of the example configs, with the in-process
executor and a finer final delta than the paper's (lead-follow 0.125, fleet3 0.25: margin refinement,
the default for Gamma*, makes these cheap), then
`scenario-farm report`.
"""

from __future__ import annotations

import json
import re
import shlex
import shutil
import subprocess
import sys
import time
from pathlib import Path

from farm.reports.summary import Summary

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
RUNS = ROOT / "runs" / "figures"
LIMIT = 300_000  # bytes per PNG

# campaign -> (example config, final delta)
CAMPAIGNS = {
    "lf-brake": ("examples/lead_follow_brake.toml", 0.125),
    "lf-idm": ("examples/lead_follow_idm.toml", 0.125),
    "fleet3-idm": ("examples/fleet3_idm.toml", 0.25),
}
# docs/figures/<name> <- runs/figures/<file>, with what it shows
FIGURE_FILES = [
    ("lead_follow_overlay.png", "lf-brake/plots/overlay.png",
     "lead-follow, brake against idm SV on the same cuts (the paper's Fig. 2): the brake-to-stop "
     "SV's safe set is the larger one"),
    ("lead_follow_idm_3d.png", "lf-idm/plots/safe_set_3d.png",
     "lead-follow / idm: the smallest safe gap p10 over (v0, v1), with units and colour bar"),
    ("lead_follow_idm_slices.png", "lf-idm/plots/safe_set_slices.png",
     "lead-follow / idm: cuts at four lead speeds v1; safe, explored and pruned, never explored"),
    ("lead_follow_idm_failures.png", "lf-idm/plots/failures.png",
     "lead-follow / idm: the recorded failing runs (first 64 that pruned the set) over the safe set"),
    ("fleet3_idm_3d.png", "fleet3-idm/plots/safe_set_3d.png",
     "fleet3 / idm: the lead-side and rear-side boundary surfaces (the paper's Fig. 4)"),
    ("fleet3_idm_slices.png", "fleet3-idm/plots/safe_set_slices.png",
     "fleet3 / idm: cuts of the total set, (v0, p10) at four v1 and (v0, p20) at four v2"),
    ("fleet3_idm_rear_side_3d.png", "fleet3-idm/plots/rear_side/safe_set_3d.png",
     "fleet3 / idm, rear-side campaign (only the p20 facet fails): its own view"),
]


def config_for(name: str) -> Path:
    """The example config with the figure's final delta (quantify.delta_min)."""
    example, delta_min = CAMPAIGNS[name]
    text = (ROOT / example).read_text()
    text, count = re.subn(r"(?m)^delta_min = .*$", f"delta_min = {delta_min}", text)
    assert count == 1, f"{example}: no delta_min line"
    path = RUNS / "configs" / f"{name}.toml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"# {example} with quantify.delta_min = {delta_min} (written by experiments/figures.py)\n"
                    + text)
    return path


def sh(*args: str) -> list[str]:
    cmd = ["scenario-farm", *args]
    print("$", shlex.join(cmd), flush=True)
    subprocess.run(cmd, check=True, cwd=ROOT, stdout=subprocess.DEVNULL)
    return cmd


def shrink(path: Path) -> None:
    """Keep a PNG under LIMIT: the figures are mostly flat colour, so a 256-colour
    palette loses nothing visible."""
    if path.stat().st_size <= LIMIT:
        return
    from PIL import Image

    Image.open(path).convert("RGB").quantize(256, method=Image.Quantize.MEDIANCUT).save(path, optimize=True)


def run() -> dict:
    t0 = time.monotonic()
    commands, summaries = [], {}
    for name in CAMPAIGNS:
        cfg = config_for(name)
        commands.append(sh("quantify", str(cfg.relative_to(ROOT)), "--out", f"runs/figures/{name}", "--force",
                           "--executor", "local", "--quiet"))
        summaries[name] = Summary.read(RUNS / name).to_json()
    commands.append(sh("report", "runs/figures/lf-brake", "runs/figures/lf-idm", "--overlay"))
    commands.append(sh("report", "runs/figures/lf-idm"))  # adds plots/failures.png
    FIGURES.mkdir(parents=True, exist_ok=True)
    for target, source, _ in FIGURE_FILES:
        shutil.copyfile(RUNS / source, FIGURES / target)
        shrink(FIGURES / target)
    keys = ("scenario", "sv_policy", "refine", "delta_final", "rounds", "boxes", "volume_union", "volume_hull", "volume_sigma",
            "runs_committed", "elapsed_s", "result_hash", "volume_lead_side", "volume_rear_side")
    data = {"date": time.strftime("%Y-%m-%d"), "seconds": round(time.monotonic() - t0, 1),
            "commands": [shlex.join(c) for c in commands],
            "campaigns": {n: {k: s[k] for k in keys if k in s} for n, s in summaries.items()},
            "figures": [{"file": t, "from": s, "shows": w, "bytes": (FIGURES / t).stat().st_size}
                        for t, s, w in FIGURE_FILES]}
    (FIGURES / "figures.json").write_text(json.dumps(data, indent=1) + "\n")
    return data


def render() -> Path:
    data = json.loads((FIGURES / "figures.json").read_text())
    c = data["campaigns"]
    out = ["# Figures", "",
           "<!-- rendered by `python experiments/figures.py --render` from docs/figures/figures.json: edit the "
           "script, not this file -->", "",
           f"Drawn from real campaigns by `python experiments/figures.py` ({data['date']}, {data['seconds']:.0f} s "
           "on 2 cores), which runs exactly these commands (the configs are the example configs with a finer "
           "final delta, `quantify.delta_min`, written to `runs/figures/configs/`):", "", "```bash",
           *data["commands"], "```", "",
           "| campaign | SV | refine | delta_min | finest half-width | boxes | volume (union) | Sigma | runs | "
           "result hash |",
           "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |"]
    out += [f"| {n} | {s['sv_policy']} | {s.get('refine', '')} | {CAMPAIGNS[n][1]:g} | {s['delta_final']:.3g} | "
            f"{s['boxes']:,} | {s['volume_union']:,.0f} | "
            f"{s['volume_sigma']:,.0f} | {s['runs_committed']:,} | `{s['result_hash']}` |" for n, s in c.items()]
    brake, idm = c["lf-brake"], c["lf-idm"]
    out += ["", f"The brake-to-stop SV keeps the larger safe set ({brake['volume_union']:,.0f} against "
            f"{idm['volume_union']:,.0f} of {brake['volume_sigma']:,.0f}), the paper's Fig. 2 ordering.", "",
            "How to read them: slices paint three classes, **safe** (blue: in the quantified set), **unsafe** "
            "(vermillion: states the campaign explored and pruned) and **never explored** (light grey, hatched: "
            "covered by no box the campaign held or ran); SPE starts from a covering of all of Sigma, so its "
            "campaigns leave nothing unexplored and the legend keeps the class for the algorithms that do (AE, "
            "VS). Coordinates a panel does not show are held at the value its title names.", ""]
    for f in data["figures"]:
        out += [f"## {f['file']}", "", f"{f['shows']} (`runs/figures/{f['from']}`).", "",
                f"![{f['file']}](figures/{f['file']})", ""]
    path = ROOT / "docs" / "figures.md"
    path.write_text("\n".join(out))
    return path


if __name__ == "__main__":
    if sys.argv[1:] != ["--render"]:
        result = run()
        print(f"{len(result['figures'])} figures in {FIGURES} ({result['seconds']:.0f} s)")
    print(render())
