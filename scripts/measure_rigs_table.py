#!/usr/bin/env python3
"""Issue 23 tables from `hmc experiment` results (scripts/measure_rigs).

    scripts/measure_rigs_table.py [OUT_DIR] [SEEDS]    (defaults: /tmp/hmc_measure_rigs, "1 2 3")

Reads OUT_DIR/E_<rig>_s<seed>/results.json for rig in generator, linear, broad
(those present) and
prints, in Markdown: one table per rig (rows seed x material x noise), the
check of every issue-23 target (a)-(e) with each miss and its numbers, and
the local share / gain per noise level (f). Every number comes from the JSON.
"""
import json, os, sys

out = sys.argv[1] if len(sys.argv) > 1 else '/tmp/hmc_measure_rigs'
seeds = [int(s) for s in (sys.argv[2] if len(sys.argv) > 2 else '1 2 3').split()]
RIGS = ['generator', 'linear', 'broad']
LINEAR_RIGS = ('linear', 'broad')  # rigs whose combos are in the dataset's span
KINDS = ['dataset', 'combos', 'performance', 'heldout', 'mixed']
BASELINES = ['blendshape', 'blendshape-bounded', 'interp', 'lgi-rbf']
DETAIL_OTHERS = ['lgi'] + BASELINES          # "lowest" among the compared methods
FLICKER_FLOOR = 0.002                        # both below: the row counts as met
FLICKER_FACTOR = 1.5
VERIFY_MAX = 1e-3


def mm(v):
    if v is None:
        return 'n/a'
    return '%.2e' % v if 0 < abs(v) < 0.001 else '%.4f' % v


def load(rig, seed):
    path = os.path.join(out, 'E_%s_s%d' % (rig, seed), 'results.json')
    if not os.path.exists(path):
        return None
    d = json.load(open(path))
    rows = {}
    for r in d['rows']:
        rows[(r['kind'], r['noise_mm'], r['method'])] = r
    return d, rows


def fmean(r):
    return r['face']['mean_mm']


def pct(x):
    return 'n/a' if x is None else '%.1f' % (100 * x)


def gain(rows, k, n):
    if (k, n, 'robust-global') not in rows:
        return None
    g = fmean(rows[(k, n, 'robust-global')])
    return None if g == 0 else (g - fmean(rows[(k, n, 'robust')])) / g


data = {}
for rig in RIGS:
    for s in seeds:
        got = load(rig, s)
        if got:
            data[(rig, s)] = got

misses = {x: [] for x in 'abcde'}
counts = {x: [0, 0] for x in 'abcde'}  # rows checked, rows missed
local = {}  # (rig, kind, noise) -> [(seed, share, gain)]

for rig in RIGS:
    have = [s for s in seeds if (rig, s) in data]
    if not have:
        continue
    print('### %s rig (default size), seeds %s\n' % (rig, ', '.join(map(str, have))))
    d0 = data[(rig, have[0])][0]
    print('%d vertices (face region %d), %d shapes, %d markers; face mean error (mm), '
          'detail (mm), flicker (mm/frame^2).\n' % (d0['vertices'], d0['face_region']['vertices'],
                                                    d0['shapes'], d0['markers']))
    print('| seed | material | noise (mm) | robust | best baseline | lgi | robust-global | '
          'local share (%) | local gain (%) | detail robust / best other | '
          'flicker robust / blendshape (ratio) | take (lag-1) |')
    print('|---|---|---|---|---|---|---|---|---|---|---|---|')
    for s in have:
        d, rows = data[(rig, s)]
        noises = sorted({n for (_, n, _) in rows})
        for k in KINDS:
            for n in noises:
                if (k, n, 'robust') not in rows:
                    continue
                rob = rows[(k, n, 'robust')]
                rv = fmean(rob)
                base = [(fmean(rows[(k, n, m)]), m) for m in BASELINES if (k, n, m) in rows]
                bv, bm = min(base)
                lg = rows.get((k, n, 'lgi'))
                rg = rows.get((k, n, 'robust-global'))
                share = rob.get('local_share')
                g = gain(rows, k, n)
                others = [(rows[(k, n, m)]['detail_face_mm'], m) for m in DETAIL_OTHERS
                          if (k, n, m) in rows]
                dv, dm = min(others)
                rd = rob['detail_face_mm']
                if k == 'dataset':
                    fl = 'n/a'
                else:
                    rf = rob['flicker_face_mm_per_frame2']
                    bf = rows[(k, n, 'blendshape')]['flicker_face_mm_per_frame2']
                    fl = '%.4f / %.4f (%.2f)' % (rf, bf, rf / bf if bf else float('inf'))
                take = ('%.2f %s' % (rob['take_correlation'], 'yes' if rob['take'] else 'no')
                        if 'take_correlation' in rob else 'n/a')
                print('| %d | %s | %g | %s | %s %s | %s | %s | %s | %s | %.5f / %.5f (%s) | %s | %s |' % (
                    s, k, n, mm(rv), bm, mm(bv), mm(fmean(lg)) if lg else 'n/a',
                    mm(fmean(rg)) if rg else 'n/a', pct(share),
                    'n/a' if g is None else '%+.1f' % (100 * g), rd, dv, dm, fl, take))
                local.setdefault((rig, k, n), []).append((s, share, g))
                tag = '%s s%d %s noise %g' % (rig, s, k, n)
                # (a) mean face error at or below the best baseline
                counts['a'][0] += 1
                if rv > bv:
                    counts['a'][1] += 1
                    misses['a'].append('%s: robust %.4g > %s %.4g (+%.1f %%)' % (
                        tag, rv, bm, bv, 100 * (rv / bv - 1) if bv else float('inf')))
                # (b) detail lowest on every noisy row
                if n > 0:
                    counts['b'][0] += 1
                    if rd > dv:
                        counts['b'][1] += 1
                        misses['b'].append('%s: robust detail %.4g > %s %.4g (+%.1f %%)' % (
                            tag, rd, dm, dv, 100 * (rd / dv - 1)))
                # (c) flicker on performances
                if k == 'performance':
                    counts['c'][0] += 1
                    ok = rf <= FLICKER_FACTOR * bf or (rf < FLICKER_FLOOR and bf < FLICKER_FLOOR)
                    if not ok:
                        counts['c'][1] += 1
                        misses['c'].append('%s: robust %.4f vs blendshape %.4f = %.2fx' % (
                            tag, rf, bf, rf / bf))
                # (d) verification
                if k == 'dataset' and n == 0:
                    counts['d'][0] += 1
                    fmax, amax = rob['face']['max_mm'], rob['all']['max_mm']
                    if amax > VERIFY_MAX:
                        counts['d'][1] += 1
                        misses['d'].append('%s: robust max %.3g mm (face %.3g)' % (tag, amax, fmax))
                    misses.setdefault('d_values', []).append(
                        '%s: robust max all vertices %.2e mm, face %.2e mm, mean %.2e mm' % (
                            tag, amax, fmax, rob['all']['mean_mm']))
                # (e) linear (and broad), in-span combos with noise: robust <= blendshape-bounded
                if rig in LINEAR_RIGS and k == 'combos':
                    bb = fmean(rows[(k, n, 'blendshape-bounded')])
                    line = '%s: robust %.4g vs blendshape-bounded %.4g (%+.1f %%)' % (
                        tag, rv, bb, 100 * (rv / bb - 1) if bb else float('inf'))
                    if n > 0:
                        counts['e'][0] += 1
                        if rv > bb:
                            counts['e'][1] += 1
                            misses['e'].append(line)
                    misses.setdefault('e_values', []).append(line)
    print()

names = {
    'a': '(a) mean face error at or below the best baseline (blendshape, blendshape-bounded, interp, lgi-rbf), every row',
    'b': '(b) detail error lowest (against lgi and the four baselines), every noisy row',
    'c': '(c) flicker on every performance <= %.1fx blendshape\'s (or both < %g mm/frame^2)' % (FLICKER_FACTOR, FLICKER_FLOOR),
    'd': '(d) verification: dataset, noise 0, robust max error over all vertices <= %g mm' % VERIFY_MAX,
    'e': '(e) linear and broad actors, combos with noise: robust <= blendshape-bounded',
}
print('### Targets\n')
for x in 'abcde':
    c, m = counts[x]
    print('%s: %d of %d rows met, %d missed' % (names[x], c - m, c, m))
    for line in misses[x]:
        print('- MISS %s' % line)
    if x == 'd':
        for line in misses.get('d_values', []):
            print('- %s' % line)
    if x == 'e':
        print('- all linear and broad combos rows (noise 0 is not part of the target):')
        for line in misses.get('e_values', []):
            print('  - %s' % line)
    print()

print('### (f) local share and local gain per noise level\n')
print('share of observed bundle-frames that took lgi\'s answer (%%) / gain over robust-global (%%), seeds %s\n'
      % ' / '.join(map(str, seeds)))
print('| rig | noise (mm) | ' + ' | '.join(KINDS) + ' |')
print('|---|---|' + '---|' * len(KINDS))
for rig in RIGS:
    for n in (0, 0.1, 0.2, 0.5, 1):
        cells = []
        for k in KINDS:
            v = local.get((rig, k, n))
            if not v:
                cells.append('n/a')
                continue
            cells.append('; '.join('%s, %s' % (pct(sh), 'n/a' if g is None else '%+.1f' % (100 * g))
                                   for _, sh, g in v))
        if any(c != 'n/a' for c in cells):
            print('| %s | %g | ' % (rig, n) + ' | '.join(cells) + ' |')
