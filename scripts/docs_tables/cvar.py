"""The `eval --split cvar` table (every model's mean scores over the test flights), and the
best physics model of it that the README quotes."""
from .common import f, header, table


def eval_cvar(r):
    """Every model's mean scores over the test flights (`eval --split cvar --json -`)."""
    models = r.get("models") if isinstance(r, dict) else None
    if not isinstance(models, dict) or not models:
        return None
    rows = sorted(models.items(), key=lambda kv: kv[1]["mae_w"])
    md = header("eval --split cvar --json -")
    md += (f"Mean over the test flights {', '.join(str(x) for x in r.get('flights', []))}, "
           f"scored over {r.get('scored_over', 'in_flight').replace('_', '-')} windows "
           "(in flight: measured power > 100 W), best MAE first.\n\n")
    md += table(["model", "MAE (W)", "RMSE (W)", "in-flight MAPE %", "energy error %"],
                [[f"`{n}`", f(m["mae_w"], 1), f(m["rmse_w"], 1), f(m["mape_pct"], 1), f(m["energy_err_pct"], 1)]
                 for n, m in rows])
    return md


def best(models, published):
    """The physics model with the lowest MAE: calibrated (`_cal`) or published."""
    rows = [(k, v) for k, v in models.items()
            if k != "lstm" and k.endswith("_cal") != published]
    return min(rows, key=lambda kv: kv[1]["mae_w"])[1] if rows else None
