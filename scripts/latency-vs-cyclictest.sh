#!/usr/bin/env bash
# Compare the VIDET control loop's wake-up latency with cyclictest's, back to back, same CPU,
# priority and period. Usage: scripts/latency-vs-cyclictest.sh RATE_HZ SECONDS [CPU] [PRIORITY]
# Needs: cyclictest (Debian rt-tests), python3, a release build of `videt`, root (or CAP_SYS_NICE).
set -euo pipefail
rate=${1:?rate in Hz}
seconds=${2:?seconds}
cpu=${3:-1}
prio=${4:-80}
here=$(cd "$(dirname "$0")/.." && pwd)
videt=${VIDET_BIN:-$here/target/release/videt}
interval_us=$((1000000 / rate))
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

cyclictest -m -t1 -a"$cpu" -p"$prio" -i"$interval_us" -D"$seconds" -q -h20000 \
  --histfile="$tmp/ct.txt" >/dev/null
"$videt" bench-rt --rate "$rate" --seconds "$seconds" --cpu "$cpu" --priority "$prio" --json >"$tmp/videt.json"

python3 - "$tmp/ct.txt" "$tmp/videt.json" "$interval_us" <<'PY'
import json, sys
hist_path, videt_path, period_us = sys.argv[1], sys.argv[2], int(sys.argv[3])
counts, overflow, maximum = {}, 0, 0
for line in open(hist_path):
    if line.startswith('#'):
        if 'Histogram Overflows' in line:
            overflow = int(line.split(':')[1].split()[0])
        if 'Max Latencies' in line:
            maximum = int(line.split(':')[1].split()[0])
        continue
    parts = line.split()
    if len(parts) >= 2:
        counts[int(parts[0])] = int(parts[1])
total = sum(counts.values()) + overflow
def quantile(q):
    rank, seen = max(1, int(q * total + 0.999999)), 0
    for us in sorted(counts):
        seen += counts[us]
        if seen >= rank:
            return float(min(us + 1, maximum))
    return float(maximum)
late = sum(c for us, c in counts.items() if us >= period_us) + overflow
ct = {'p50': quantile(0.5), 'p99': quantile(0.99), 'p999': quantile(0.999), 'max': float(maximum)}
v = json.load(open(videt_path))
w = v['wake_latency_us']
print(f"rate {v['rate_hz']} Hz, {v['seconds']} s each; cyclictest samples {total}, loop periods {v['cycles']}")
print(f"{'':22}{'p50':>10}{'p99':>10}{'p99.9':>10}{'max':>10}  (µs)")
print(f"{'cyclictest':22}{ct['p50']:10.1f}{ct['p99']:10.1f}{ct['p999']:10.1f}{ct['max']:10.1f}")
print(f"{'videt loop':22}{w['p50']:10.1f}{w['p99']:10.1f}{w['p999']:10.1f}{w['max']:10.1f}")
ratio = lambda a, b: a / b if b > 0 else float('nan')
print(f"{'ratio loop/cyclictest':22}{ratio(w['p50'],ct['p50']):10.2f}{ratio(w['p99'],ct['p99']):10.2f}{ratio(w['p999'],ct['p999']):10.2f}{ratio(w['max'],ct['max']):10.2f}")
print(f"cyclictest wake-ups later than one period: {late}; loop overruns: {v['overruns']} (loop wake-ups later than one period: {v['late_wakeups_over_period']})")
print(f"loop compute time: p50 {v['compute_us']['p50']:.1f} p99 {v['compute_us']['p99']:.1f} max {v['compute_us']['max']:.1f} µs")
PY
