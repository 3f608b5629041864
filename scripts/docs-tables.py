#!/usr/bin/env python3
"""Write the book's results tables (docs/src/generated/*.md) from the commands' --json.

The tables in the book are never typed by hand: a refit changes the JSON, this script
rewrites the tables, and `make docs` builds them in. The generated files are committed,
so the book builds without the data set.

    scripts/docs-tables.py                 # run the commands (binary + data set needed)
    scripts/docs-tables.py --if-available  # what `make docs` runs: refresh when the binary is
                                           # up to date with src/ and the data set is there,
                                           # else keep the committed tables (with a note)
    scripts/docs-tables.py --no-eval       # skip `eval --split cvar`
    scripts/docs-tables.py --from-json DIR # read DIR/battery-eval.json, DIR/plan-eval.json,
                                           # DIR/eval-cvar.json instead of running anything
    scripts/docs-tables.py --check         # write nothing: fail when a committed table or a
                                           # figure in the README's "Headline figures" is not
                                           # what the commands print now (`make test` runs it
                                           # with --if-available)

The README's headline figures are prose, written by hand, so they are checked instead of
written: `readme_claims` says, per command, which figure must stand there and how it is
rounded.

The LightGBM tables (lgbm-cv.md, lgbm-test.md) are always written from the committed
docs/src/generated/lgbm-cv.json (`lab/scripts/lgbm_cv.py`'s --json; half an hour to tune, so
not rerun here) and, for the LSTM's rows, the model cards and `cv.csv` of
config/models/lstm-m100 (shipped) and config/models/lstm-m100-h128 (the paper's network).

The binary is $DRONEWATT_BIN, else ${CARGO_TARGET_DIR:-target}/debug/dronewatt-lab, the lab's
(build it with `make docs-tables`, which runs `cargo build --locked --bin dronewatt-lab` first). The data
set is $DRONEWATT_DATA, else ../shared/data/m100/flights.csv.gz. Each command's JSON is
also kept in ${CARGO_TARGET_DIR:-target}/docs-json/ for a later --from-json.
"""

import argparse
import json
import os
import subprocess
import sys
from pathlib import Path

from docs_tables.battery import battery_eval, battery_params
from docs_tables.common import OUT, ROOT, note
from docs_tables.cvar import eval_cvar
from docs_tables.lgbm import lgbm_tables
from docs_tables.plan import plan_eval_flights, plan_eval_members, plan_eval_routes, plan_eval_targets
from docs_tables.readme import headline, readme_claims
from docs_tables.spec import spec_tables

# (file stem, command line after the binary). All three take ~9 s together in a dev build.
COMMANDS = {
    "battery-eval": ["battery-eval", "--json", "-"],
    "plan-eval": ["plan-eval", "--json", "-"],
    "eval-cvar": ["eval", "--split", "cvar", "--json", "-"],
}


WRITERS = {
    "battery-eval": [("battery-eval.md", battery_eval), ("battery-params.md", battery_params)],
    "plan-eval": [("plan-eval-flights.md", plan_eval_flights), ("plan-eval-targets.md", plan_eval_targets),
                  ("plan-eval-members.md", plan_eval_members), ("plan-eval-routes.md", plan_eval_routes)],
    "eval-cvar": [("eval-cvar.md", eval_cvar)],
}


def up_to_date(binary):
    """The binary is newer than every source file it is built from."""
    t = binary.stat().st_mtime
    for d in ("src", "lab/src"):
        for p in (ROOT / d).rglob("*"):
            if p.is_file() and p.stat().st_mtime > t:
                return False
    for p in (ROOT / "Cargo.toml", ROOT / "lab" / "Cargo.toml", ROOT / "Cargo.lock"):
        if p.exists() and p.stat().st_mtime > t:
            return False
    return True


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from-json", metavar="DIR", type=Path)
    ap.add_argument("--if-available", action="store_true")
    ap.add_argument("--no-eval", action="store_true", help="skip `eval --split cvar` (a few seconds)")
    ap.add_argument("--check", action="store_true",
                    help="write nothing; fail when a committed table or a README headline figure is stale")
    a = ap.parse_args()

    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    cache = target / "docs-json"
    binary = Path(os.environ.get("DRONEWATT_BIN", target / "debug" / "dronewatt-lab"))
    data = Path(os.environ.get("DRONEWATT_DATA", ROOT.parent / "shared" / "data" / "m100" / "flights.csv.gz"))

    # from the committed JSON: needs neither the binary nor the data set
    lgbm_stale = lgbm_tables(check=a.check) + spec_tables(check=a.check)
    wanted = ["battery-eval", "plan-eval"] + ([] if a.no_eval else ["eval-cvar"])
    results = {}
    if a.from_json:
        for name in wanted:
            p = a.from_json / f"{name}.json"
            if p.exists():
                results[name] = json.loads(p.read_text())
            else:
                note(f"{p} missing: {name} tables kept as committed")
    else:
        why = None
        if not binary.exists():
            why = f"{binary} not built (make docs-tables builds it)"
        elif not data.exists():
            why = f"the data set {data} is absent (set DRONEWATT_DATA)"
        elif a.if_available and not up_to_date(binary):
            why = f"{binary} is older than src/ (make docs-tables rebuilds it)"
        if why:
            if a.if_available:
                note(f"{why}: keeping the committed tables in {OUT.relative_to(ROOT)}")
                for s in lgbm_stale:
                    note(f"stale: {s}")
                return 1 if lgbm_stale else 0
            note(why)
            return 1
        cache.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, DRONEWATT_DATA=str(data), DRONEWATT_HOME="off")
        for name in wanted:
            note(f"running dronewatt-lab {' '.join(COMMANDS[name])}")
            p = subprocess.run([str(binary)] + COMMANDS[name], cwd=ROOT, env=env,
                               capture_output=True, text=True)
            if p.returncode != 0:
                note(f"dronewatt-lab {name} failed ({p.returncode}):\n{p.stderr[-2000:]}")
                if a.if_available:
                    continue
                return 1
            (cache / f"{name}.json").write_text(p.stdout)
            results[name] = json.loads(p.stdout)

    OUT.mkdir(parents=True, exist_ok=True)
    stale = list(lgbm_stale)
    for name, r in results.items():
        for fname, fn in WRITERS[name]:
            md = fn(r)
            if md is None:
                note(f"{name}: JSON shape not recognised, {fname} not written")
                continue
            if a.check:
                if not (OUT / fname).exists() or (OUT / fname).read_text() != md:
                    stale.append(f"{(OUT / fname).relative_to(ROOT)} differs from `dronewatt-lab {name} --json`")
                continue
            (OUT / fname).write_text(md)
            note(f"wrote {(OUT / fname).relative_to(ROOT)}")
    # The README's headline figures are hand-written prose: checked, never written.
    head = headline(ROOT / "README.md")
    for name, r in results.items():
        for claim in readme_claims(name, r):
            if claim not in head:
                stale.append(f"README.md, Headline figures: `{claim}` (from `dronewatt-lab {name} --json`) is not there")
    for s in stale:
        note(f"stale: {s}")
    if stale:
        note("refresh with `make docs-tables` and edit the README's headline figures to match")
        return 1
    note(f"the tables and the README's headline figures match {', '.join(results) or 'nothing (no JSON)'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
