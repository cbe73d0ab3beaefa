"""Groups a `perf report --sort dso,sym -F overhead,sample,dso,sym` listing
into what the training step spends its time on, and the cores kept busy.

    python3 scripts/profile_categories.py symbols.txt bench.txt FREQ > profile.json

bench.txt is the benchmark's output over the same run (its step seconds and
timed step count give the wall time the samples cover). Writes JSON with
every category's share and samples, the top symbols of each, and a
Markdown table under "table".
"""
import json
import re
import sys

# First match wins; patterns are searched in "dso symbol".
CATEGORIES = [
    ("matrix products", r"gemm|nano_gemm|matmul"),
    ("kernel: page faults, scheduling, system calls", r"\[kernel"),
    ("memory management (allocator)", r"_rjem|jemalloc|je_|malloc|free|mallocx|sdallocx|rallocx|realloc|arena|tcache|extent"),
    ("element-wise math (exp, sin, ...)", r"expf|sinf|cosf|logf|powf|__exp|__sin|__cos|__log|libm|sincos|erf|tanh"),
    ("reductions and scans", r"reduce|sum_dim|sum\b|cumsum|cumulative|cumprod|argmax|argmin|max_dim|min_dim|mean"),
    ("copies, layout, gather/scatter", r"memcpy|memmove|memset|copy|slice|cat\b|::cat|gather|scatter|select|expand|repeat|contiguous|strided|permute|swap_dims|reshape|into_data|from_data|to_vec|clone"),
    ("element-wise ops (add, mul, relu, ...)", r"burn_flex::ops::(binary|unary|float|activation|comparison|mask|bool)|burn_flex::simd|macerator|inplace|zip|binary|unary|relu|clamp|mask_where|powi|sqrt"),
    ("threading (rayon, futex, yield)", r"rayon|crossbeam|futex|sched_yield|parking|__schedule|pthread"),
    ("autodiff graph and bookkeeping", r"burn_autodiff|burn_backend|burn_tensor|hashbrown|Arc|drop_in_place"),
]


def parse(path):
    rows = []
    pat = re.compile(r"^\s*([\d.]+)%\s+(\d+)\s+(\S+)\s+\[(.)\]\s+(.*)$")
    for line in open(path, encoding="utf-8", errors="replace"):
        m = pat.match(line)
        if m:
            pct, samples, dso, kind, sym = m.groups()
            rows.append((float(pct), int(samples), dso, kind, sym.strip()))
    return rows


def category(dso, kind, sym):
    text = f"{dso} {sym}"
    if kind == "k":
        text = "[kernel " + text
    for name, pattern in CATEGORIES:
        if re.search(pattern, text):
            return name
    return "other"


def main():
    symbols, bench, freq = sys.argv[1], sys.argv[2], float(sys.argv[3])
    rows = sorted(parse(symbols), key=lambda r: -r[1])
    total = sum(r[1] for r in rows) or 1
    cats = {}
    for pct, samples, dso, kind, sym in rows:
        c = cats.setdefault(category(dso, kind, sym), {"samples": 0, "top": []})
        c["samples"] += samples
        if len(c["top"]) < 8:
            c["top"].append({"share": samples / total, "dso": dso, "symbol": sym[:160]})
    text = open(bench, encoding="utf-8").read()
    steps = re.search(r"Adam; (\d+) timed steps", text)
    steps = int(steps.group(1)) if steps else None
    cpu = re.search(r"^cpu: (.*)$", text, re.M)
    secs = [float(m.group(1)) for m in re.finditer(r"^flex\s+.{28}\s+([\d.]+)\s", text, re.M)]
    wall = steps * sum(secs) if steps and secs else None
    busy = (total / freq) / wall if wall else None
    order = sorted(cats.items(), key=lambda kv: -kv[1]["samples"])
    lines = [
        f"CPU: {cpu.group(1) if cpu else 'unknown'}; {total} samples at {freq:.0f} Hz over "
        + (f"{wall:.1f} s of timed steps: {busy:.2f} cores busy on average" if wall else "an unknown wall time"),
        "",
        "| where the time goes | share of CPU time | CPU seconds |",
        "|---|---|---|",
    ]
    for name, c in order:
        lines.append(f"| {name} | {100 * c['samples'] / total:.1f}% | {c['samples'] / freq:.2f} |")
    print(json.dumps({
        "cpu": cpu.group(1) if cpu else None,
        "samples": total,
        "frequency_hz": freq,
        "timed_wall_seconds": wall,
        "busy_cores": busy,
        "categories": {k: {"share": v["samples"] / total, "cpu_seconds": v["samples"] / freq, "top": v["top"]} for k, v in order},
        "table": "\n".join(lines),
    }, indent=2))


if __name__ == "__main__":
    main()
