"""The `plan-eval` tables: the test flights, the targets, the forecast's members and the
routes."""
from .common import f, header, table


def plan_eval_flights(r):
    rows = []
    for x in r["test_flights"]:
        g = x["payload_g"]
        rows.append([
            x["flight"], x["route"], f"{x['speed_m_s']:g}", f"{g:g}", x["altitude"], x["geometry_from"],
            f"{x['airborne_s']:.0f} / {x['planned_s']:.0f}",
            f(x["measured_wh"]), f(x["p50_wh"]), f(x["p90_wh"]), f(x["preflight_err_pct"]),
            "yes" if x["p90_covers"] else "no", f(x["baseline_preflight_err_pct"]),
            f(x["live_measured_rest_wh"]), f(x["live_forecast_rest_wh"]), f(x["live_err_pct"]),
            f(x["baseline_gcs_err_pct"]), f(x["baseline_err_pct"]),
        ])
    md = header("plan-eval --json -")
    md += table(["flight", "route", "m/s", "g", "alt m", "waypoints from", "airborne / planned s",
                 "measured Wh", "P50 Wh", "P90 Wh", "pre-flight err %", "P90 covers",
                 "baseline pre-flight err %", "rest measured Wh", "rest forecast Wh", "live err %",
                 "baseline live err %, ground station's clock", "baseline live err %, dronewatt's clock"], rows)
    return md


def plan_eval_targets(r):
    te, tr = r["test"], r["training"]

    def met(ok, extra=""):
        return ("met" if ok else "**missed**") + extra

    worst = max(r["test_flights"], key=lambda x: x["preflight_err_pct"])
    worst_at = ": " + worst["route"] + " flight " + str(worst["flight"])
    rows = [
        ["pre-flight median error", "≤ 3 %",
         f"**{te['preflight_median_err_pct']:.2f} %** ({met(te['preflight_median_err_pct'] <= 3)})",
         f"{tr['preflight_median_err_pct']:.2f} %"],
        ["pre-flight max error", "≤ 8 %",
         f"**{te['preflight_max_err_pct']:.2f} %** ({met(te['preflight_max_err_pct'] <= 8, worst_at)})",
         f"{tr['preflight_max_err_pct']:.1f} %"],
        ["P90 covers measured", "≥ 85 %",
         f"**{te['p90_coverage_pct']:.0f} %** ({met(te['p90_coverage_pct'] >= 85)})",
         f"{tr['p90_coverage_pct']:.0f} %"],
        ["live at 50 %, remaining-energy median error (issue 25)", "≤ 1.5 %",
         f"**{te['live_median_err_pct']:.2f} %** ({met(te['live_median_err_pct'] <= 1.5)})",
         f"{tr['live_median_err_pct']:.2f} %"],
        ["baseline live, the ground station's clock", "2×",
         f"{te['baseline_gcs_live_median_err_pct']:.1f} % (dronewatt **{te['live_advantage_gcs']:.0f}×**: {met(te['live_advantage_gcs'] >= 2)})",
         f"{tr['baseline_gcs_live_median_err_pct']:.1f} % ({tr['live_advantage_gcs']:.0f}×)"],
        ["baseline live, dronewatt's clock (issue 25)", "1.5×",
         f"{te['baseline_live_median_err_pct']:.2f} % (dronewatt **{te['live_advantage']:.1f}×**: {met(te['live_advantage'] >= 1.5)})",
         f"{tr['baseline_live_median_err_pct']:.2f} % ({tr['live_advantage']:.1f}×)"],
        ["baseline pre-flight median error", "2×",
         f"{te['baseline_preflight_median_err_pct']:.2f} % (dronewatt **{te['preflight_advantage']:.1f}×**: {met(te['preflight_advantage'] >= 2)})",
         f"{tr['baseline_preflight_median_err_pct']:.2f} % ({tr['preflight_advantage']:.1f}×)"],
    ]
    md = header("plan-eval --json -")
    md += (f"Fit on {tr['flights']} training flights, scored on {te['flights']} test flights.\n\n")
    md += table(["", "target", "test flights", "training flights"], rows)
    return md


def plan_eval_members(r):
    rows = []
    for m in r.get("members_alone", []):
        t = m["test"]
        rows.append([f"`{m['model']}`", f"{m['training_err_pct']:.2f}", f"{m['tie_share_pct']:.0f} %",
                     f"{t['preflight_median_err_pct']:.2f}", f"{t['preflight_max_err_pct']:.2f}",
                     f"{t['p90_coverage_pct']:.0f} %", f"{t['live_median_err_pct']:.2f}",
                     f"{t['baseline_live_median_err_pct']:.2f}"])
    te = r["test"]
    rows.append(["**the members' mean (shipped)**", f"{r['training']['preflight_median_err_pct']:.2f}", "—",
                 f"**{te['preflight_median_err_pct']:.2f}**", f"{te['preflight_max_err_pct']:.2f}",
                 f"{te['p90_coverage_pct']:.0f} %", f"**{te['live_median_err_pct']:.2f}**",
                 f"{te['baseline_live_median_err_pct']:.2f}"])
    md = header("plan-eval --json -")
    md += table(["member", "training median err %", "resamples no worse than the best",
                 "test pre-flight median %", "test pre-flight max %", "test P90 covers",
                 "test live median %", "baseline live (dronewatt's clock) %"], rows)
    return md


def plan_eval_routes(r):
    """The live forecast at half time per route against both baselines' clocks, the test
    flights beside the training flights' rolling validation."""
    routes = r.get("routes")
    if not routes:
        return None

    def cell(x):
        if not x:
            return ["—", "—", "—"]
        return [f"{x['live_median_err_pct']:.2f} % ({x['flights']})",
                f"{x['baseline_gcs_live_median_err_pct']:.1f} % ({x['live_advantage_gcs']:.1f}×)",
                f"{x['baseline_live_median_err_pct']:.2f} % ({x['live_advantage']:.1f}×)"]
    rows = [[rs["route"]] + cell(rs.get("test")) + cell(rs.get("training")) for rs in routes]
    md = header("plan-eval --json -")
    md += ("Live at 50 %, median error of the remaining energy per route (flights), and each baseline "
           "(mean power so far × the time left) with the ground station's clock and with dronewatt's "
           "(dronewatt's advantage); training flights by rolling validation.\n\n")
    md += table(["route", "test: dronewatt", "test: baseline, ground station's clock",
                 "test: baseline, dronewatt's clock", "training: dronewatt",
                 "training: baseline, ground station's clock", "training: baseline, dronewatt's clock"], rows)
    return md
