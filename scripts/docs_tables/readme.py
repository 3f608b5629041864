"""The README's "Headline figures": which figure of each command's JSON must stand there, and
the section itself (checked, never written: it is prose)."""
from .cvar import best


def readme_claims(name, r):
    """The strings the README's headline figures must hold for this command's JSON."""
    if name == "plan-eval":
        t = r["test"]
        return [f"**{t['preflight_median_err_pct']:.2f} %**", f"(max {t['preflight_max_err_pct']:.2f} %)",
                f"P90 covers {t['p90_coverage_pct']:.0f} %", f"**{t['live_median_err_pct']:.2f} %**",
                f"{t['live_advantage_gcs']:.0f}×", f"**{t['live_advantage']:.1f}×**"]
    if name == "battery-eval":
        t = r["test"]
        return [f"**{t['ocv_energy_mae_wh']:.2f} Wh**", f"**{t['px4_36_energy_mae_wh']:.1f} Wh**",
                f"({t['full_pack_start_energy_err_wh']:.0f} Wh", f"**{1e3 * t['ocv_end_v_mae_v']:.0f} mV**",
                f"**{t['ecm_median_rmse_v']:.3f} V**", f"**{t['halftime_min_v_mae']:.3f} V**",
                f"{t['preflight_plan_min_v_mae']:.3f} V", f"**{t['landing_energy_ours_mae_wh']:.2f} Wh**",
                f"**{t['landing_energy_px4_mae_wh']:.1f} Wh**", f"{t['landing_energy_ardupilot_mae_wh']:.0f} Wh"]
    if name == "eval-cvar":
        m = r["models"]
        out = [f"**{m['lstm']['mape_pct']:.1f} %**", f"energy error {m['lstm']['energy_err_pct']:.1f} %"]
        for published in (False, True):
            b = best(m, published)
            if b:
                out.append(f"{b['mape_pct']:.1f} %")
        return out
    return []


def headline(readme):
    """The README's "Headline figures" section."""
    text = readme.read_text()
    start = text.find("## Headline figures")
    end = text.find("\n## ", start + 1)
    return text[start:end if end > 0 else len(text)] if start >= 0 else ""
