"""report: figures, the brake-vs-idm overlay, failure trajectories and the HTML page of
real campaigns, from the CLI."""

import json
import subprocess
import sys


def campaign(tmp_path, policy):
    (tmp_path / f"{policy}.toml").write_text(
        f'[scenario]\nname = "lead-follow"\nsv_policy = "{policy}"\n[actions]\nmode = "adversarial"\n'
        f'[quantify]\ndelta0 = 4.0\ndelta_min = 2.0\nhorizon = 50\n[farm]\nexecutor = "local"\n')
    out = tmp_path / policy
    r = subprocess.run([sys.executable, "-m", "farm", "quantify", str(tmp_path / f"{policy}.toml"), "--out", str(out),
                        "--quiet"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    return out


def test_overlay_failures_and_html(tmp_path):
    brake, idm = campaign(tmp_path, "brake"), campaign(tmp_path, "idm")
    r = subprocess.run([sys.executable, "-m", "farm", "report", str(brake), str(idm), "--overlay"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert (brake / "plots" / "overlay.png").stat().st_size > 10_000
    r = subprocess.run([sys.executable, "-m", "farm", "report", str(idm), "--html"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert (idm / "plots" / "failures.png").stat().st_size > 10_000  # its recorded failing runs
    page = (idm / "report.html").read_text()
    summary = json.loads((idm / "summary.json").read_text())
    assert summary["guarantee"].split(",")[0] in page and page.count("<img") >= 3
    assert "<script" not in page  # self-contained, nothing runs
    r = subprocess.run([sys.executable, "-m", "farm", "report", str(idm), "--overlay"], capture_output=True,
                       text=True)
    assert r.returncode == 2 and "two or more" in r.stderr
