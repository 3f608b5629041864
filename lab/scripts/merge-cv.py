#!/usr/bin/env python3
"""Join the `cv.csv` files of a cross-validation spread over processes or machines.

`dronewatt-lab train --cv K --cv-folds 0,1,2 --out A` and `... --cv-folds 3,4 --out B` (the same
other flags) each write their folds' rows; this joins them into one `cv.csv` with every fold,
in fold order, and the means and medians recomputed over all of them:

    lab/scripts/merge-cv.py A/cv.csv B/cv.csv > cv.csv

Rows are matched on the setting (dropout, learning rate, batch, hidden cells, init seeds,
stride, relative loss, plateau decay, target lag, readout); a fold that appears twice, or a setting missing a fold another has, is an error.
Standard library only.
"""
import csv
import statistics
import sys

KEY = ("dropout", "learning_rate", "batch_size", "hidden", "init_seeds", "stride", "relative_loss",
       "plateau_decay", "target_lag", "readout")
FOLD_COLS = ("fold_held_out", "fold_best_epoch", "fold_inner_val_mae_w", "fold_mae_w", "fold_rmse_w",
             "fold_mape_in_flight_pct", "fold_energy_error_pct", "fold_band_coverage_pct", "fold_band_q_w")


def band_widening(qs):
    """The band's widening over the folds, as `train --cv` computes it (`cv_band_widening`):
    the mean of the folds' signed widenings, floored at 0."""
    m = statistics.fmean(qs)
    return m if m != m else max(m, 0.0)  # NaN stays NaN

# Summary column -> (per-fold column, statistic).
SUMMARY = {
    "avg_rmse_w": ("fold_rmse_w", statistics.fmean),
    "avg_mae_w": ("fold_mae_w", statistics.fmean),
    "median_mae_w": ("fold_mae_w", statistics.median),
    "avg_mape_in_flight_pct": ("fold_mape_in_flight_pct", statistics.fmean),
    "median_mape_in_flight_pct": ("fold_mape_in_flight_pct", statistics.median),
    "avg_energy_error_pct": ("fold_energy_error_pct", statistics.fmean),
    "median_energy_error_pct": ("fold_energy_error_pct", statistics.median),
    "avg_band_coverage_pct": ("fold_band_coverage_pct", statistics.fmean),
    "cv_band_widen_w": ("fold_band_q_w", band_widening),
}


def main(paths):
    if len(paths) < 2:
        sys.exit(__doc__)
    header, merged = None, {}
    for path in paths:
        with open(path, newline="") as fh:
            reader = csv.DictReader(fh)
            if header is None:
                header = reader.fieldnames
            elif reader.fieldnames != header:
                sys.exit(f"{path}: its columns differ from {paths[0]}'s")
            for row in reader:
                key = tuple(row.get(k) or "" for k in KEY)  # older files lack the later columns
                folds = merged.setdefault(key, {})
                for i, fold in enumerate(row["fold_index"].split(";")):
                    if fold in folds:
                        sys.exit(f"{path}: fold {fold} of setting {key} appears twice")
                    folds[fold] = {c: row[c].split(";")[i] for c in FOLD_COLS if row.get(c)} | {"row": row}
    counts = {len(f) for f in merged.values()}
    if len(counts) != 1:
        sys.exit(f"settings hold different numbers of folds: {sorted(counts)}")
    out = csv.DictWriter(sys.stdout, fieldnames=header, lineterminator="\n")
    out.writeheader()
    for key, folds in merged.items():
        order = sorted(folds, key=int)
        row = dict(folds[order[0]]["row"])
        # Columns added later (the band's) are joined where every fold has them.
        cols = [c for c in FOLD_COLS if all(c in folds[f] for f in order)]
        for c in cols:
            row[c] = ";".join(folds[f][c] for f in order)
        row["fold_index"] = ";".join(order)
        row["folds"] = str(max(int(folds[f]["row"]["folds"]) for f in order))
        for col, (src, stat) in SUMMARY.items():
            if src in cols and col in row:
                row[col] = f"{stat([float(folds[f][src]) for f in order]):.3f}"
        out.writerow(row)


if __name__ == "__main__":
    main(sys.argv[1:])
