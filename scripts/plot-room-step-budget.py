#!/usr/bin/env python3
"""The multiply-adds a ray of the two fields' matrix products on the
bench room, beside the fast step's microseconds a ray as profiled and
what 5 times the Mip-NeRF field's rays a second leaves for them.

    scripts/plot-room-step-budget.py MULADDS_CSV BUDGET_CSV OUT.png

MULADDS_CSV has the columns `field`, `part` and `multiply_adds_a_ray`
(a row `all` a field, skipped); BUDGET_CSV has `bar`, `part` and
`microseconds_a_ray` (the parts of a bar stacked in their order).
"""
import sys

from plot_csv import plt, rows


def main():
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    muladds = [r for r in rows(sys.argv[1]) if r["part"] != "all"]
    budget = rows(sys.argv[2])
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5))

    fields = list(dict.fromkeys(r["field"] for r in muladds))
    for i, field in enumerate(fields):
        bottom = 0.0
        for r in (r for r in muladds if r["field"] == field):
            value = int(r["multiply_adds_a_ray"]) / 1e6
            left.bar(i, value, bottom=bottom, width=0.6, edgecolor="white")
            if value > 0.3:
                left.text(i, bottom + value / 2, r["part"].split(" (")[0],
                          ha="center", va="center", fontsize=7)
            bottom += value
        left.text(i, bottom, f"{bottom:.2f}", ha="center", va="bottom")
    left.set_xticks(range(len(fields)), ["fast" if f == "fast" else "Mip-NeRF" for f in fields])
    left.set_ylabel("million multiply-adds a ray (forward + backward)")
    left.set_title("The matrix products of a training ray, bench room defaults")

    bars = list(dict.fromkeys(r["bar"] for r in budget))
    colours = {"matrix products (gemm)": "tab:blue",
               "hash encoding (forward and backward)": "tab:orange",
               "everything else": "tab:gray", "all the rest": "tab:green"}
    for i, bar in enumerate(bars):
        bottom = 0.0
        for r in (r for r in budget if r["bar"] == bar):
            value = float(r["microseconds_a_ray"])
            right.bar(i, value, bottom=bottom, width=0.6,
                      color=colours.get(r["part"], "tab:purple"), edgecolor="white")
            right.text(i, bottom + value / 2, f"{r['part'].replace(' (', chr(10) + '(')}\n{value:.0f} µs",
                       ha="center", va="center", fontsize=7)
            bottom += value
    right.set_xticks(range(len(bars)), [b.replace(" (", "\n(") for b in bars], fontsize=8)
    right.set_ylabel("µs a training ray (one core)")
    right.set_title("The fast step on a Zen 3, and what 5x leaves")
    fig.tight_layout()
    fig.savefig(sys.argv[3], dpi=110)


if __name__ == "__main__":
    main()
