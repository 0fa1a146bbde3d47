#!/usr/bin/env python3
"""Track fixes a TD would make on the review page, with a synthetic shot's
truth standing in for the TD's eye (docs/review.md, "Fixing the hard
preset's wrong names").

    scripts/fixes_from_truth.py TRACKS_2D.csv SHOT/dots_2d.csv OUT.csv [--tracks 10]
        [--any [--every-run]]

A row is wrong as `hmc eval-tracks` counts it (tracking/track_eval.cc): a
wrong name when it is nearer another visible marker's dot than its own (or
the truth does not place its marker in the image), else off when it is more
than 2 px from its own marker's dot centre.

Default: the tracks (camera, marker) with the most wrong-name rows are
fixed on their first wrong-name frame as a TD does on the page: the dot
that carries the wrong label is renamed to the marker whose dot it is
(`rename` with the dot's x,y), and the marker's own dot, where the truth
sees it, is given back to it (`move` to the dot's centre: the drag of the
label onto its dot); a label on a dot of no marker in view is taken off
(`unname`).

--any: the tracks with the most wrong rows of either kind (the off rows
are mostly partly hidden dots whose seen part's centroid is 2-3 px off the
dot's centre, under a pixel on the page's proxies), each made `absent` on
its first wrong frame (with --every-run: at the start of every run of wrong
frames) and named again (`rename` at the true dot centre) on the first
later frame where the dot is whole and the row was not wrong (a name on
another marker's dot renamed as above). Prints what it chose to stderr."""
import argparse, csv, math, sys
from collections import defaultdict

ap = argparse.ArgumentParser()
ap.add_argument('tracks'); ap.add_argument('truth'); ap.add_argument('out')
ap.add_argument('--tracks', dest='n', type=int, default=10)
ap.add_argument('--any', action='store_true')
ap.add_argument('--every-run', action='store_true')
args = ap.parse_args()

truth, visible = {}, defaultdict(list)
for r in csv.DictReader(open(args.truth)):
    k = (int(r['frame']), r['camera'], r['marker'])
    px = (float(r['x']), float(r['y']))
    if r['cx']:
        centre = (float(r['cx']), float(r['cy']))
    elif r.get('wcx'):
        centre = (float(r['wcx']), float(r['wcy']))
    else:
        centre = px
    truth[k] = dict(px=px, centre=centre, disc=r['disc'], visible=r['visible'] == '1')
    if r['visible'] == '1':
        visible[(k[0], k[1])].append((r['marker'], px))
dist = lambda a, b: math.hypot(a[0] - b[0], a[1] - b[1])

wrong = defaultdict(list)  # (camera, marker) -> [(frame, kind, other marker, pixel)]
rows = 0
for r in csv.DictReader(open(args.tracks)):
    rows += 1
    f, cam, m = int(r['frame']), r['camera'], r['marker']
    p = (float(r['x']), float(r['y']))
    own = truth.get((f, cam, m))
    if own is None:
        near = [(dist(p, q), n) for n, q in visible[(f, cam)]]
        wrong[(cam, m)].append((f, 'other', min(near)[1] if near else None, p))
        continue
    d_own = dist(p, own['px'])
    others = [(dist(p, q), n) for n, q in visible[(f, cam)] if n != m and dist(p, q) < d_own]
    if others:
        wrong[(cam, m)].append((f, 'other', min(others)[1], p))
    elif dist(p, own['centre']) > 2:
        wrong[(cam, m)].append((f, 'off', None, p))


def count(track):
    return len([x for x in wrong[track] if args.any or x[1] == 'other'])


fixes, covered = [], 0
for cam, m in sorted((t for t in wrong if count(t)), key=lambda t: (-count(t), t))[:args.n]:
    lst = sorted(x for x in wrong[(cam, m)] if args.any or x[1] == 'other')
    covered += len(lst)
    runs = []
    for x in lst:
        if runs and x[0] == runs[-1][-1][0] + 1:
            runs[-1].append(x)
        else:
            runs.append([x])
    wrong_frames = {x[0] for x in lst}
    for run in runs if args.every_run else runs[:1]:
        f, kind, other, p = run[0]
        if kind == 'other':
            # The label sits on another marker's dot: that dot is renamed
            # to its marker, and the label goes back onto its own dot.
            if other:
                fixes.append((f, cam, m, 'rename', p, other))
            else:
                fixes.append((f, cam, m, 'unname', p, ''))
            own = truth.get((f, cam, m))
            if not args.any and own and own['visible']:
                fixes.append((f, cam, m, 'move', own['centre'], ''))
            continue
        fixes.append((f, cam, m, 'absent', None, ''))
        after = run[-1][0] if args.every_run else f
        g = next((g for g in range(after + 1, after + 100000) if (g, cam, m) in truth
                  and truth[(g, cam, m)]['disc'] == 'full' and g not in wrong_frames), None)
        if g is not None:
            fixes.append((g, cam, '', 'rename', truth[(g, cam, m)]['centre'], m))
    print(f'{cam} {m}: {len(lst)} wrong rows from frame {lst[0][0]} ({lst[0][1]})', file=sys.stderr)
total = sum(len(v) for v in wrong.values())
names = sum(1 for v in wrong.values() for x in v if x[1] == 'other')
print(f'{rows} rows, {total} wrong ({names} wrong names); the {args.n} worst tracks hold {covered}'
      f' {"wrong rows" if args.any else "wrong names"}; {len(fixes)} fixes', file=sys.stderr)
with open(args.out, 'w') as o:
    o.write('frame,camera,marker,action,x,y,to\n')
    for f, cam, m, a, p, to in sorted(fixes, key=lambda x: x[0]):
        xy = f'{p[0]:.3f},{p[1]:.3f}' if p else ','
        o.write(f'{f},{cam},{m},{a},{xy},{to}\n')
