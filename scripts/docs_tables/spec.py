"""The spec-sheet tables of the book (docs/src/spec-sheet.md), written by scripts/docs-tables.py
from the committed JSON of scripts/spec-priors.py, scripts/peer-multirotor.py,
scripts/spec-m100.py and scripts/peer-cruise-check.py (moved out of docs-tables.py, which had
grown past 600 lines)."""
import json

from .common import OUT, ROOT, f, header, note, table


# `scripts/spec-priors.py --json` (the hover-efficiency prior across airframes, leave one out)
# and `scripts/peer-multirotor.py --json` (the spec-sheet forecast against the multirotor
# package's Tarot T18): their JSON is committed beside the tables (see docs/src/spec-sheet.md).
SPEC_JSON = OUT / "spec-priors.json"
PEER_JSON = OUT / "peer-multirotor.json"


M100_JSON = OUT / "spec-m100.json"


def spec_priors(r):
    rows = [[a["airframe"], f(a["kg"], 3), a["rotors"], f(a["prop_m"], 4), f(a["hover_w"], 1),
             f(a["eta_h"], 3), f"{f(a['loao_eta'], 3)} ± {f(a['loao_sd'], 2)}", a["loao_form"].replace("_", " "),
             f(a["loao_hover_w"], 1), f"{a['loao_err_pct']:+.1f} %", "yes" if a["loao_p90_covers"] else "no",
             a["source"]]
            for a in r["airframes"]]
    forms = ", ".join(f"{k.replace('_', ' ')} {f(v, 3)}" for k, v in r["forms"].items())
    return (header("scripts/spec-priors.py --json").replace("dronewatt-lab scripts/", "scripts/")
            + table(["airframe", "take-off kg", "rotors", "prop m", "hover W", "η_h",
                     "prior without it (η_h ± log-sd)", "its form", "its forecast W", "error", "P90 covers",
                     "source"], rows)
            + f"\nEach form's leave-one-airframe-out median |ln η_h error| over all airframes: {forms} "
              f"(shipped: {r['form_all'].replace('_', ' ')}). A constant over all airframes: η_h = "
              f"{f(r['eta_h_median'], 3)}, log-spread {f(r['eta_h_log_sd'], 3)}. Leave-one-airframe-out median "
              f"|error| of the hover power {f(r['loao_median_abs_err_pct'], 1)} %, its P90 covering "
              f"{f(r['loao_p90_cover_pct'], 1)} % of the rows.\n")


def peer_multirotor(r):
    out = header("scripts/peer-multirotor.py --json").replace("dronewatt-lab scripts/", "scripts/")
    pct = lambda v: "—" if v is None else f"{v:+.1f} %"
    for key, af in r["airframes"].items():
        rows = []
        for fl in af["flights"]:
            st = {s["stage"]: s for s in fl["stages"]}
            row = [fl["flight"], fl["speed"], f"{fl['wind'][0]} m/s from {fl['wind'][1]}°", f(fl["truth_wh"], 1)]
            for name in ("spec", "hover"):
                q = st.get(name)
                row += [f(q["p50"], 1), f(q["p90"], 1), pct(q["err_pct"])] if q else ["—"] * 3
            lv = st.get("live") or {}
            row += [pct(lv.get("before_err_pct")), pct(lv.get("after_err_pct")), pct(lv.get("err_pct"))]
            q = st.get("learned")
            row += [f(q["p50"], 1), pct(q["err_pct"]), f(q.get("adapted_mape_pct"), 1)] if q else ["—"] * 3
            rows.append(row)
        pr = af["prior_held_out"]
        out += (f"\n**{af['airframe']}** (figure of merit {f(af['figure_of_merit'], 2)}, motors "
                f"{f(100 * af['motor_eff'], 1)} % in its hover; body C_D·A {af['body_cda_m2']} m², "
                f"{af['body_cda_source']}; held out: η_h prior {f(pr['eta_h'], 3)} ± {f(pr['log_sd'], 2)}, "
                f"{pr['form'].replace('_', ' ')})\n\n")
        out += table(["flight", "speed m/s", "wind", "peer's energy Wh", "spec P50", "spec P90", "spec error",
                      "after hover P50", "P90", "error", "live: rest of mission, priors", "live: after the hover",
                      "plan --vehicle <stored>", "learned P50", "error", "learned: adapted power MAPE %"], rows) + "\n"
        for st, v in af["summary"].items():
            if "median_abs_err_pct" in v:
                out += (f"- **{st}**: median |error| {f(v['median_abs_err_pct'], 1)} %, P90 ≥ the peer's energy on "
                        f"{f(v['p90_cover_pct'], 1)} % of {v['flights']} flights\n")
            elif st == "live_mission":
                out += (f"- **live, the rest of the mission** (monitor/replay, the first hover calibrating): median "
                        f"|error| {f(v['before_median_abs_err_pct'], 1)} % on the priors just before, "
                        f"{f(v['after_median_abs_err_pct'], 1)} % just after, {v['flights']} flights\n")
            elif st == "learned_adapted_power":
                out += (f"- **learned, live adapted power**: median MAPE {f(v['median_mape_pct'], 1)} % over "
                        f"{v['flights']} flights\n")
    return out


def spec_stages(peer, m100):
    """The airframe × stage table: each airframe held out, its median |error| at each stage."""
    def cell(v, cover=None):
        if v is None:
            return "—"
        return f"{f(v, 1)} %" + (f" (P90 covers {f(cover, 0)} %)" if cover is not None else "")
    rows = []
    for key, af in peer["airframes"].items():
        s = af["summary"]
        g = lambda k, field="median_abs_err_pct": (s.get(k) or {}).get(field)
        n = (s.get("spec") or {}).get("flights")
        rows.append([af["airframe"], n, cell(g("spec"), g("spec", "p90_cover_pct")), cell(g("hover")), cell(g("live")),
                     cell((s.get("live_mission") or {}).get("after_median_abs_err_pct")), cell(g("learned")),
                     cell((s.get("learned_adapted_power") or {}).get("median_mape_pct"))])
    if m100:
        s = m100["summary"]
        rows.append(["DJI M100 (data set, its own paths)", s["spec"]["flights"],
                     cell(s["spec"]["median_abs_err_pct"], s["spec"]["p90_cover_pct"]),
                     cell((s.get("hover") or {}).get("median_abs_err_pct")), "—", "—",
                     "1.95 % (the shipped M100 forecast, fitted on 178 of its flights, not 3: plan-eval, the book's Mission page)", "—"])
    return (header("scripts/peer-multirotor.py --json, scripts/spec-m100.py --json")
            .replace("dronewatt-lab scripts/", "scripts/")
            + table(["airframe (held out)", "flights", "spec sheet: plan P50, median abs error",
                     "after the first hover: plan --hover-w", "plan --vehicle <stored after replay>",
                     "live: rest of mission after the hover", "after learn on 3 (+1) flights", "live adapted power MAPE"],
                    rows))


CRUISE_JSON = OUT / "peer-cruise.json"
CRUISE_VARIANTS = [("hover", "after the hover (drag prior)"), ("cruise_drag", "+ first cruise fits C_D·A"),
                   ("cruise_factor", "+ first cruise scales forward flight"),
                   ("peer_form", "diagnostic: no translational lift, no parasite power")]


def peer_cruise(r):
    """`scripts/peer-cruise-check.py --json`: what the first hover leaves, and the first cruise."""
    out = header("scripts/peer-cruise-check.py --json").replace("dronewatt-lab scripts/", "scripts/")
    rows = []
    for af in r["airframes"].values():
        for k, name in CRUISE_VARIANTS:
            s = af["summary"][k]
            rows.append([af["airframe"], name, f"{f(s['median_abs_err_pct'], 1)} %", f"{f(s['max_abs_err_pct'], 1)} %",
                         f"{f(s['p90_cover_pct'], 0)} %"])
    out += table(["airframe", "plan energy, momentum theory", "median abs error", "largest abs error",
                  f"P90 ({f(r['p90_ratio'], 3)} × P50) covers"], rows)
    for af in r["airframes"].values():
        out += (f"\n**{af['airframe']}** (η_h {f(af['eta_h'], 3)} from its hover; C_D·A prior "
                f"{f(af['cda_prior_m2'], 4)} m², the peer's {af['peer_cda_m2']} m²)\n\n")
        out += table(["flight", "speed m/s", "wind", "peer's energy Wh", "first cruise W", "C_D·A fitted m²",
                      "cruise factor"] + [name for _, name in CRUISE_VARIANTS],
                     [[fl["flight"], fl["speed"], f"{fl['wind'][0]} m/s from {fl['wind'][1]}°", f(fl["truth_wh"], 1),
                       f(fl["first_cruise_w"], 1), f(fl["cda_fit_m2"], 4), f(fl["cruise_factor"], 3)]
                      + [f"{fl['err_pct'][k]:+.1f} %" for k, _ in CRUISE_VARIANTS] for fl in af["flights"]])
    return out


SHARE_JSON = OUT / "profile-share.json"
SHARE_NAMES = {"t18": "Tarot T18 (peer)", "mavic": "DJI Mavic Pro (peer)", "m100": "DJI M100 (training flights, every 3rd)"}


def profile_share(r):
    """`scripts/profile-share-fit.py --json`: each airframe's plan error at each profile share,
    and the share each held-out airframe gets (fitted on the others)."""
    out = header("scripts/profile-share-fit.py --json").replace("dronewatt-lab scripts/", "scripts/")
    keys = list(SHARE_NAMES)
    rows = []
    for s, by in r["grid"].items():
        rows.append([s] + [f"{f(by[k]['spec']['median_abs_err_pct'], 1)} % / {f(by[k]['hover']['median_abs_err_pct'], 1)} %"
                           for k in keys])
    out += table(["profile share s"] + [f"{SHARE_NAMES[k]}: spec / after hover" for k in keys], rows)
    out += "\n" + table(["held out", "s fitted on the other two", "their mean after-hover error"],
                        [[SHARE_NAMES[k], f(v["profile_share"], 2), f"{f(v['mean_fitting_hover_err_pct'], 2)} %"]
                         for k, v in r["held_out"].items()]
                        + [["none (shipped)", f(r["shipped"]["profile_share"], 2),
                            f"{f(r['shipped']['mean_hover_err_pct'], 2)} %"]])
    return out


def spec_tables(check=False):
    """Write the spec-sheet tables from their committed JSON (with `check`: the stale ones)."""
    stale = []
    jobs = [(SPEC_JSON, "spec-priors.md", spec_priors), (PEER_JSON, "peer-multirotor.md", peer_multirotor),
            (CRUISE_JSON, "peer-cruise.md", peer_cruise), (SHARE_JSON, "profile-share.md", profile_share)]
    if PEER_JSON.exists():
        m100 = json.loads(M100_JSON.read_text()) if M100_JSON.exists() else None
        jobs.append((PEER_JSON, "spec-stages.md", lambda r: spec_stages(r, m100)))
    for path, fname, fn in jobs:
        if not path.exists():
            note(f"{path.relative_to(ROOT)} absent: {fname} kept as committed")
            continue
        md = fn(json.loads(path.read_text()))
        if check:
            if not (OUT / fname).exists() or (OUT / fname).read_text() != md:
                stale.append(f"{(OUT / fname).relative_to(ROOT)} differs from its JSON")
            continue
        (OUT / fname).write_text(md)
        note(f"wrote {(OUT / fname).relative_to(ROOT)}")
    return stale
