#!/usr/bin/env python3
"""By-pack cross-validation of candidate time-to-low rules on ProgPy's fit packs (issue 44,
round 6): each argument is a `progpy_score.py --set fit --json` of one candidate (a scratch
build with `round6-lab.patch` applied, its `DW_*` variables set). Leave one fit pack out,
choose on the other packs by the fewest forecasts more than 25 % late, then the median
|error|, and score the choice on the pack left out.

  lab_bypack_cv.py /tmp/grid-A.json /tmp/grid-B.json ...
"""
import json
import statistics
import sys


def pack(name):
    return name.rsplit("-", 1)[0]


def errs(flights, packs):
    return [v for x in flights if pack(x["name"]) in packs for v in x["ttl"].values()]


def score(es):
    have = [e for e in es if e is not None]
    med = statistics.median([abs(e) for e in have]) if have else float("inf")
    return (sum(1 for e in have if e > 0.25), med)


def main():
    runs = {f: json.load(open(f))["per_flight"] for f in sys.argv[1:]}
    packs = sorted({pack(x["name"]) for fl in runs.values() for x in fl})
    for k, fl in sorted(runs.items()):
        late, med = score(errs(fl, packs))
        print(f"{k}: late {late}, median {100 * med:.1f} %")
    out = []
    for p in packs:
        others = [q for q in packs if q != p]
        best = min(runs, key=lambda k: score(errs(runs[k], others)))
        e = errs(runs[best], [p])
        out += e
        print("held out", p, "chose", best, [None if v is None else round(100 * v) for v in e])
    late, med = score(out)
    print(f"CV: {late} of {len(out)} more than 25 % late, median {100 * med:.1f} %")


if __name__ == "__main__":
    main()
