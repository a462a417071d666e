#!/usr/bin/env python3
"""Side by side: the figures of bench/compare.sh's logs, before (a) and after (b).

    bench/compare_summary.py OUT_DIR [NAME...]

For every line that reads the same in every run of a benchmark (its words, with the numbers
left out), prints its words and, for each number that is not the same in every run,
"mean a -> mean b (b/a, noise)": noise is the largest spread between the runs of one build,
relative to their mean (the yardstick for b/a). Lines whose shape differs between the builds (a
benchmark that changed its output) are listed apart.
"""
import glob
import os
import re
import sys

NUMBER = re.compile(r"-?\d+(?:\.\d+)?(?:e[-+]?\d+)?")
# Lines about the run, not the code: dates, the machine's load.
SKIP = ("Load Average", "#-#-#T#:#:#")


def shape(line):
    return NUMBER.sub("#", line.strip())


def numbers(line):
    return [float(x) for x in NUMBER.findall(line)]


def runs(out, name, side):
    files = sorted(glob.glob(os.path.join(out, f"{name}.{side}.*.log")))
    return [open(f).read().splitlines()[1:] for f in files]  # past the "== ..." header


def spread(values):
    mean = sum(values) / len(values)
    return (max(values) - min(values)) / abs(mean) if mean else 0.0


def summarize(out, name):
    a, b = runs(out, name, "a"), runs(out, name, "b")
    if not a or not b:
        return
    print(f"## {name}_bench: {len(a)} runs of a, {len(b)} of b")
    # Lines matched by their shape and their position among the lines of that shape.
    def index(lines):
        seen, keyed = {}, {}
        for line in lines:
            s = shape(line)
            if "#" not in s:
                continue
            k = (s, seen.get(s, 0))
            seen[s] = k[1] + 1
            keyed[k] = line
        return keyed
    ia, ib = [index(r) for r in a], [index(r) for r in b]
    different = []
    for key, first in ia[0].items():
        if not all(key in r for r in ia + ib):
            different.append(first.strip())
            continue
        va = [numbers(r[key]) for r in ia]
        vb = [numbers(r[key]) for r in ib]
        if any(word in key[0] for word in SKIP):
            continue
        cells = []
        for k in range(len(va[0])):
            xa, xb = [v[k] for v in va], [v[k] for v in vb]
            if all(x == xa[0] for x in xa + xb):
                continue  # a constant (a size, a count)
            ma, mb = sum(xa) / len(xa), sum(xb) / len(xb)
            ratio = f"{mb / ma:.2f}" if ma else "-"
            noise = max(spread(xa), spread(xb))
            cells.append(f"{ma:.4g} -> {mb:.4g} ({ratio}, {100 * noise:.0f}%)")
        if cells:
            label = NUMBER.sub("#", first.strip())[:60]
            print(f"  {label:<60}  " + "  ".join(cells))
    if different:
        print(f"  (lines that differ between the builds: {len(different)})")
        for line in different[:20]:
            print(f"    {line}")
    print()


def main():
    out = sys.argv[1]
    names = sys.argv[2:] or ["qota", "embree", "planet", "shadow"]
    for name in names:
        summarize(out, name)


if __name__ == "__main__":
    main()
