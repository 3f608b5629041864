"""The LightGBM tables (lgbm-cv.md, lgbm-test.md, lgbm-lags.md), always written from the
committed JSON of `lab/scripts/lgbm_cv.py`, with the LSTM's rows from its model cards and
`cv.csv`."""
import json

from .common import OUT, ROOT, f, note, table


# `lab/scripts/lgbm_cv.py` tunes LightGBM on the LSTM's by-flight folds (half an hour on one
# core, so it is not run here): its JSON, figures only, is committed beside the tables.
LGBM_JSON = OUT / "lgbm-cv.json"
LSTM_DIR = ROOT / "config" / "models" / "lstm-m100"
LSTM_CARD = LSTM_DIR / "card.toml"
PAPER_CARD = ROOT / "config" / "models" / "lstm-m100-h128" / "card.toml"


# The ensembles shipped before this card's, by how their recipe differs from the card's (the
# labels `changes` gives) and their number of members: their rows stay in `cv.csv`, named for
# when they shipped (all on 2026-11-26, newest first).
REPLACED = {
    ((), 4): "shipped before this one",
    (("the final readout",), 3): "shipped before that",
    (("the absolute loss", "the final readout"), 3): "shipped first",
}


def lstm_cv_rows():
    """The LSTM's rows of the shipped model's `cv.csv` (`train --cv 5 --seed 7`, on LightGBM's
    folds): (name, {mae_w, mape_in_flight_pct, energy_error_pct: {mean, median}}). The row
    whose network and training match the card is the shipped one; the others are named by how
    they differ from it."""
    import csv
    import tomllib
    path = LSTM_DIR / "cv.csv"
    try:
        rows = list(csv.DictReader(path.open()))
        card = tomllib.loads(LSTM_CARD.read_text())
    except (OSError, tomllib.TOMLDecodeError) as e:
        note(f"{path}: no LSTM CV rows ({e})")
        return []
    train = card.get("training", {})
    shipped = {"hidden": str(card.get("hidden")), "stride": str(train.get("stride")),
               "relative_loss": float(train.get("relative_loss", 0)),
               "plateau_decay": float(train.get("plateau_decay", 1)),
               "members": 1 + len(card.get("members", [])), "target_lag": int(card.get("target_lag", 0)),
               "readout": card.get("readout", "final"), "trees": "trees" in card}

    def changes(r):
        # Columns added later (absent in older rows): the loss's relative weight, the plateau decay,
        # the target lag, the readout.
        c = []
        if r["stride"] != shipped["stride"]:
            c.append(f"stride {r['stride']}")
        lam = float(r.get("relative_loss") or 0)
        if lam != shipped["relative_loss"]:
            c.append(f"relative loss λ {lam:g}" if lam else "the absolute loss")
        if float(r.get("plateau_decay") or 1) != shipped["plateau_decay"]:
            c.append(f"plateau decay {float(r.get('plateau_decay') or 1):g}")
        if r.get("target_lag") and int(r["target_lag"]) != shipped["target_lag"]:
            c.append(f"target lag {int(r['target_lag'])} ({int(r['target_lag']) / 10:g} s)")
        if (r.get("readout") or "Final").lower() != shipped["readout"]:
            c.append(f"the {r['readout'].lower()} readout")
        return c

    out = []
    for r in rows:
        seeds = r.get("init_seeds", "").split(";")
        c = changes(r)
        replaced = REPLACED.get((tuple(c), len(seeds)))
        if r["hidden"] != shipped["hidden"]:
            name = (f"LSTM, one network × {r['hidden']} cells, stride {r['stride']} "
                    "(the paper's network, shipped before the ensembles)")
        elif len(seeds) > 1:
            base = f"LSTM, ensemble of {len(seeds)} × {r['hidden']} cells"
            if not c and len(seeds) == shipped["members"]:
                loss = f", relative loss λ {shipped['relative_loss']:g}" if shipped["relative_loss"] else ""
                readout = ", the instant readout" if shipped["readout"] != "final" else ""
                what = "shipped, in the blend below" if shipped["trees"] else "shipped"
                name = f"{base}, stride {r['stride']}{loss}{readout} ({what})"
            elif replaced:
                name = f"{base}, stride {r['stride']}{''.join(', ' + x for x in c)} ({replaced}, replaced)"
            else:
                what = ", ".join(c) if c else "the shipped recipe otherwise"
                name = f"{base}, {what} (candidate, not shipped)"
        elif not c:
            name = f"LSTM, its first member alone ({r['hidden']} cells, stride {r['stride']})"
        elif replaced := next((v for (k, _), v in REPLACED.items() if k == tuple(c)), None):
            name = f"LSTM, the ensemble {replaced}: its first member alone"
        else:
            name = f"LSTM, the first member (init seed {seeds[0]}) with {', '.join(c)} (candidate, not shipped)"
        stat = {k: {"mean": float(r[f"avg_{k}"]), "median": float(r[f"median_{k}"])}
                for k in ("mape_in_flight_pct", "energy_error_pct")}
        stat["mae_w"] = {"mean": float(r["avg_mae_w"]), "median": float(r["median_mae_w"])}
        out.append((name, stat))
        if shipped["trees"] and name.endswith("(shipped, in the blend below)"):
            out.extend(blend_cv_rows(card))
    return out


BLEND_JSON = OUT / "blend-cv.json"
# The blend shipped before this one (the four-member ensemble with the same trees, at 0.7).
BLEND_REPLACED_JSON = OUT / "blend-cv-four.json"


def blend_cv_rows(card):
    """The shipped blend's out-of-fold row (`lab/scripts/blend_cv.py --json`, committed as
    docs/src/generated/blend-cv.json), and the replaced blend's (`blend-cv-four.json`): the
    network's share chosen for each fold on the others."""
    import statistics
    out = []
    for path, shipped in ((BLEND_JSON, True), (BLEND_REPLACED_JSON, False)):
        try:
            b = json.loads(path.read_text())
        except OSError as e:
            note(f"{path}: no blend CV row ({e})")
            continue
        folds = b["folds"]
        shares = "/".join(f"{x['weight_lstm']:g}" for x in folds)
        stat = {k: {"mean": statistics.mean(x["blend"][k] for x in folds),
                    "median": statistics.median(x["blend"][k] for x in folds)}
                for k in ("mae_w", "mape_in_flight_pct", "energy_error_pct")}
        if shipped:
            name = (f"**the shipped model: that ensemble blended with LightGBM #0 on its inputs, out of fold "
                    f"(network's share {shares} a fold, chosen on the others; {card['trees']['weight_lstm']:g} "
                    f"on all, shipped; `{path.name}`)**")
        else:
            name = (f"the ensemble of four blended with the same trees, out of fold (share {shares} a fold; "
                    f"{b['weight_lstm_pooled']:g} on all; shipped before this one, replaced; `{path.name}`)")
        out.append((name, stat))
    return out


def lgbm_header():
    return ("<!-- Generated by scripts/docs-tables.py from docs/src/generated/lgbm-cv.json "
            "(`lab/scripts/lgbm_cv.py`). Do not edit: run `make docs-tables`. -->\n\n")


def lgbm_cv(r):
    """The CV table: every configuration on the training flights' folds, best CV MAE first."""
    rows = sorted(r.get("configs", []), key=lambda c: c["mae_w"]["mean"])
    if not rows:
        return None
    md = lgbm_header()
    sizes = ", ".join(str(n) for n in r.get("fold_flights", []))
    md += (f"{r['folds']}-fold by-flight cross-validation on the {r['training_flights']} training flights "
           f"(folds of {sizes} flights: `offline::data::cv_folds`, the folds `dronewatt-lab train --cv "
           f"{r['folds']} --seed 7` validates the LSTM on), target lag {r['target_lag']} samples "
           f"({r['target_lag'] / 10:.1f} s). Mean over the held-out folds, median in brackets; MAE over "
           "every window, MAPE over in-flight windows (measured ≥ 100 W), energy error per flight, "
           "averaged. Rule, fixed before the run: the lowest mean CV MAE chooses the configuration and "
           f"its tree count. Every configuration, #0 included, trains on every 2nd window of its flights "
           "with bagging 0.5 and a tree count chosen on the folds, every 25 up to 40 / learning rate (“cap”: "
           "the best was the last tried); the untuned row is `lgbm_baseline.py`'s recipe (every window, "
           "bagging 0.8, early stopping on 12 % of the fold's training flights, trees per fold). "
           f"Wall time {r['wall_s'] / 60:.0f} min on one core for the {len(rows)} configurations × "
           f"{r['folds']} folds (`{r['command']}`, windows from `{r['export']}`)"
           + (f", {r['untuned']['wall_s'] / 60:.0f} min for the untuned row" if r.get("untuned") else "")
           + ".\n\n")
    head = ["configuration", "leaves", "learning rate", "min data in leaf", "feature fraction", "L2",
            "trees", "CV MAE (W)", "CV MAPE %", "CV energy error %"]

    def cells(c):
        return [f(c["mae_w"]["mean"]) + f" ({f(c['mae_w']['median'])})",
                f(c["mape_in_flight_pct"]["mean"]) + f" ({f(c['mape_in_flight_pct']['median'])})",
                f(c["energy_error_pct"]["mean"]) + f" ({f(c['energy_error_pct']['median'])})"]
    body = []
    for c in rows:
        p = c["params"]
        name = f"#{c['index']}" + (" (baseline's parameters)" if c["index"] == 0 else "")
        if c["index"] == r.get("chosen"):
            name = f"**{name}, chosen**"
        body.append([name, p["num_leaves"], p["learning_rate"], p["min_data_in_leaf"], p["feature_fraction"],
                     p["lambda_l2"], f"{c['trees']}" + (" (cap)" if c["trees"] == c.get("max_trees") else "")]
                    + cells(c))
    u = r.get("untuned")
    if u:
        body.append(["untuned (`lgbm_baseline.py`'s recipe)", 63, 0.05, 20, 0.8, 0,
                     "/".join(str(t) for t in u["trees"])] + cells(u))
    for name, c in lstm_cv_rows():
        body.append([name, "", "", "", "", "", ""] + cells(c))
    md += table(head, body)
    md += ("\nThe LSTM rows are `config/models/lstm-m100/cv.csv`, from the shipped model's recipe "
           "with `--cv 5 --seed 7` (the command in its model card): on each fold every member is "
           "early-stopped on an inner validation split of that fold's training flights (`--val-frac`, "
           "by flight, seeded), never on the held-out fold, and the held-out flights are scored as the "
           "model card scores the test flights, every window through the live chain; the first "
           "member alone is scored on the same folds beside the ensemble, and the paper's network "
           "(`config/models/lstm-m100-h128`'s recipe) is cross-validated on the same folds too. "
           "The candidates (rows marked so) are the shipped recipe with one flag changed "
           "(`--stride`, `--plateau-decay`, `--relative-loss`, `--target-lag`, `--readout`), screened as one network "
           "(init seed 7, the ensemble's first member) and, where the screen passed its rule, as the "
           "ensemble; the rules and the order they ran in are in the model card. A row at another target "
           "lag answers a different question (the estimate for an older instant) and compares with "
           "LightGBM at that lag (`lgbm-lags.md`), not with the rows above at 0.3 s. "
           "Each ensemble's cross-validation ran as two processes (`--cv-folds`), joined by "
           "`lab/scripts/merge-cv.py`.\n")
    return md


def lgbm_test(r):
    """The test table: the CV-chosen LightGBM, the untuned one, the shipped LSTM's card."""
    t = r.get("test")
    if not t:
        return None
    md = lgbm_header()
    md += (f"Test flights {', '.join(str(x) for x in t['test_flights'])}, scored once with the configuration "
           f"cross-validation chose (trained on every training flight; `{t['command']}`), all windows, "
           f"target lag {r['target_lag'] / 10:.1f} s. MAE pooled over the test windows, in-flight MAPE "
           "pooled, energy error averaged over the flights, as the model card scores the LSTM.\n\n")
    rows = []
    tu = t["tuned"]
    rows.append([f"LightGBM + lags, tuned on the folds (#{tu['index']}, {tu['trees']} trees)", f(tu["mae_w"], 1),
                 f(tu["flight_276_mae_w"], 1), f(tu["mape_in_flight_pct"]), f(tu["energy_error_pct"])])
    un = t["untuned"]
    rows.append([f"LightGBM + lags, untuned (`lgbm_baseline.py`, {un['trees']} trees)", f(un["mae_w"], 1),
                 f(un["flight_276_mae_w"], 1), f(un["mape_in_flight_pct"]), f(un["energy_error_pct"])])
    import tomllib
    for what, card in (("shipped (model card)", LSTM_CARD),
                       ("the paper's network, shipped before (its card)", PAPER_CARD)):
        try:
            c = tomllib.loads(card.read_text())
            n = 1 + len(c.get("members", []))
            net = f"ensemble of {n} × {c['hidden']} cells" if n > 1 else f"{c['layers']} × {c['hidden']} cells"
            lam = c.get("training", {}).get("relative_loss", 0)
            net += f", relative loss λ {lam:g}" if lam else ""
            net += f", the {c['readout']} readout" if c.get("readout", "final") != "final" else ""
            if "trees" in c:
                net += f", blended with LightGBM (network's share {c['trees']['weight_lstm']:g})"
            m = c["metrics"]
            rows.append([f"LSTM, {net}, {what}", f(m["mae_w"], 1), f(m["flight_276_mae_w"], 1),
                         f(m["mape_in_flight_pct"]), f(m["energy_error_pct"])])
        except (OSError, KeyError) as e:
            note(f"{card}: no LSTM row ({e})")
    md += table(["model", "test MAE (W)", "flight 276 MAE (W)", "in-flight MAPE %", "energy error %"], rows)
    return md


LGBM_LAGS_JSON = OUT / "lgbm-lags.json"


def lag_set(lags):
    """1, 3, 9 / 1, 3–7, 9 / 1, 3–19: a sorted set of lags, runs as ranges."""
    runs, start = [], lags[0]
    for a, b in zip(lags, lags[1:] + [None]):
        if b != a + 1:
            runs.append(f"{start}" if start == a else f"{start}–{a}")
            start = b
    return ", ".join(runs)


def lgbm_lags(r):
    """LightGBM's chosen configuration at other target lags and with more feature lags (issue 25's
    fair-peer check): how much each model gains from the samples after and before the instant."""
    runs = r.get("runs", [])
    if not runs:
        return None
    md = ("<!-- Generated by scripts/docs-tables.py from docs/src/generated/lgbm-lags.json "
          "(`lab/scripts/lgbm_cv.py --only 0`). Do not edit: run `make docs-tables`. -->\n\n")
    md += (f"{r['what']}: {r['folds']}-fold by-flight cross-validation on the LSTM's folds, the same rule "
           f"for the tree count (`{r['command']}`, windows from `{r['export']}`). The target lag L is the "
           "estimate's instant, L samples before the newest. The export holds the newest sample and its copies "
           "lagged 1, 3 and 9 samples; `--lags N` (N > 3) adds the lags 4 to N, shifted within each flight, so "
           "lag 2 is never among them: the column lists the lags each row saw, and what they hold around "
           "the instant (the LSTM's window of 10 sees all L after it and 9 − L before). "
           "Inputs: `paper`, the 21 features as exported (longitude, latitude, altitude above sea level); `home`, "
           "the LSTM's (`--features home` at export); `+ physics`, with the seven physics models' estimates of "
           "the window at published parameters (`--physics`). "
           "Mean over the held-out folds, median in brackets.\n\n")
    body = []
    for x in runs:
        lag, n = x["target_lag"], x["feature_lags"]
        # The export holds lags 1, 3 and 9; `--lags N` shifts in 4..N (lag 2 is never among them).
        lags = sorted({0, 1, 3, 9} | set(range(4, n + 1)))
        after = sum(1 for k in lags if k < lag)
        before = [k - lag for k in lags if k > lag]
        seen = ("the instant" if lag in lags else "not the instant") + f", {after} of {lag} after"
        seen += f", {len(before)} before (up to {max(before)})" if before else ", none before"
        body.append([f"{lag} ({lag / 10:g} s)", lag_set(lags[1:]), x.get("inputs", "paper"), seen,
                     f"{x['trees']}" + (" (cap)" if x["trees"] == x.get("max_trees") else ""),
                     f(x["mae_w"]["mean"]) + f" ({f(x['mae_w']['median'])})",
                     f(x["mape_in_flight_pct"]["mean"]) + f" ({f(x['mape_in_flight_pct']['median'])})",
                     f(x["energy_error_pct"]["mean"]) + f" ({f(x['energy_error_pct']['median'])})",
                     f"{x['wall_s'] / 60:.1f}"])
    md += table(["target lag", "lags seen", "inputs", "around the instant", "trees", "CV MAE (W)",
                 "CV MAPE %", "CV energy error %", "wall (min, one core)"], body)
    return md


def lgbm_tables(check=False):
    """Write the LightGBM tables (with `check`: write nothing, return the stale ones)."""
    stale = []
    if not LGBM_JSON.exists():
        note(f"{LGBM_JSON.relative_to(ROOT)} absent: LightGBM tables kept as committed")
        return stale
    r = json.loads(LGBM_JSON.read_text())
    jobs = [("lgbm-cv.md", lgbm_cv, r), ("lgbm-test.md", lgbm_test, r)]
    if LGBM_LAGS_JSON.exists():
        jobs.append(("lgbm-lags.md", lgbm_lags, json.loads(LGBM_LAGS_JSON.read_text())))
    for fname, fn, r in jobs:
        md = fn(r)
        if md is None:
            note(f"nothing for {fname} in its JSON, not written")
            continue
        if check:
            if not (OUT / fname).exists() or (OUT / fname).read_text() != md:
                stale.append(f"{(OUT / fname).relative_to(ROOT)} differs from its JSON and the LSTM's card")
            continue
        (OUT / fname).write_text(md)
        note(f"wrote {(OUT / fname).relative_to(ROOT)}")
    return stale
