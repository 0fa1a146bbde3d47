#!/usr/bin/env python3
"""Blocks one camera's view of a share of the marker-frames a synthetic
shot's dots_2d.csv shows in both cameras (scripts/measure_rays): the row of
a camera drawn at random gets visible 0 and disc hidden, as if an occluder
stood between it and the dot. Deterministic by seed.
  block_views.py DOTS_IN DOTS_OUT SHARE SEED"""
import csv
import random
import sys

src, dst, share, seed = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
with open(src, newline="") as f:
    reader = csv.DictReader(f)
    fields = reader.fieldnames
    rows = list(reader)
seen = {}
for i, r in enumerate(rows):
    if r["visible"] == "1":
        seen.setdefault((r["frame"], r["marker"]), []).append(i)
rng = random.Random(seed)
blocked = 0
for key in sorted(seen):
    views = seen[key]
    if len(views) >= 2 and rng.random() < share:
        i = rng.choice(views)
        rows[i]["visible"] = "0"
        rows[i]["disc"] = "hidden"
        for k in ("cx", "cy", "wcx", "wcy"):
            if k in rows[i]:
                rows[i][k] = ""
        blocked += 1
with open(dst, "w", newline="") as f:
    writer = csv.DictWriter(f, fieldnames=fields, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
print("block_views: %d of %d marker-frames seen by two cameras blocked in one" %
      (blocked, sum(1 for v in seen.values() if len(v) >= 2)))
