#!/usr/bin/env bash
# Real-time figures: runs the benchmarks that measure them (release build) and prints ONE
# table: figure | measured | target | today | status.
#
# The tests check function only, with generous liveness time-outs; the figures that follow
# the host's load (reaction time, cycle misses, jitter, where-at-t on real time, SDO rates)
# are measured here. Each benchmark prints `REALTIME <name> <value> <unit>` lines (and
# `REALTIME-SKIP <name> <reason>` for what cannot run here, e.g. veth without root, and
# `REALTIME-NOTE <name> <text>` for what explains a figure, e.g. why the juggler tripped).
#
# Targets: the project's requirement where one exists, else the figure it reported
# (docs/decisions.md, specs/powerlink.md, the benchmarks' own documentation); "today" is
# the figure the project reported before these benchmarks (or the first measurement here).
# Status: MET, NOT MET (worse than the target: host noise or a regression, reported only),
# GROSS REGRESSION (worse than 10x the target: fails), skipped (e.g. not root).
# Exit status: non-zero only on a gross regression or a measurement that failed to run.
#
# Usage: bash scripts/realtime.sh   (as root for the veth rows; ~4-5 minutes on 2 cores once
# the benchmarks are built, e.g. by `cargo bench --workspace --no-run`)
# Scheduling: the figures are those of a deployment for real-time work, `--realtime auto`
# (SCHED_FIFO for cyclic, device and simulator threads as root, nice levels otherwise): the
# benchmarks read MOTUS_REALTIME (default here: auto). The one scenario whose threads poll
# (POWERLINK 400 us on veth: polling MN and CNs) runs at the default priority: SCHED_FIFO
# threads that never block would take both cores of a small host.
# Knobs: MOTUS_REALTIME (auto), MOTUS_EPL_SECONDS (5), MOTUS_EPL_POLLING_SECONDS (20, POWERLINK
# 400 us polling), MOTUS_SYNC_SECONDS (15), MOTUS_REACTION_EVENTS (10000), MOTUS_NFV2_BENCH_SECONDS (3),
# MOTUS_NFV2_WHERE_SECONDS (20); REALTIME_OUT (target/realtime) keeps each benchmark's log;
# REALTIME_TABLE_ONLY=1 prints the table of the logs already there without measuring.
set -uo pipefail
cd "$(dirname "$0")/.."
export CARGO_TERM_COLOR=never
export BENCH_QUICK=1
export MOTUS_REALTIME="${MOTUS_REALTIME:-auto}"
export MOTUS_EPL_SECONDS="${MOTUS_EPL_SECONDS:-5}"
# The two figures a few seconds of host noise move most (a p99 of 1 % of the periods, a miss
# rate of tenths of a percent) are measured over longer runs.
export MOTUS_EPL_POLLING_SECONDS="${MOTUS_EPL_POLLING_SECONDS:-20}"
export MOTUS_SYNC_SECONDS="${MOTUS_SYNC_SECONDS:-15}"
export MOTUS_REACTION_EVENTS="${MOTUS_REACTION_EVENTS:-10000}"
export MOTUS_NFV2_BENCH_SECONDS="${MOTUS_NFV2_BENCH_SECONDS:-3}"
export MOTUS_NFV2_WHERE_SECONDS="${MOTUS_NFV2_WHERE_SECONDS:-20}"
out="${REALTIME_OUT:-target/realtime}"
mkdir -p "$out"
table_only="${REALTIME_TABLE_ONLY:-0}"
[ "$table_only" = 1 ] || rm -f "$out"/*.log

# Short criterion runs: the figures of interest are the REALTIME lines, not criterion's.
criterion_args=(--warm-up-time=0.5 --measurement-time=1 --noplot)
failed=()

# measure NAME BENCH [extra args]: `cargo bench --workspace --bench BENCH` (the workspace's
# feature set, as `cargo bench --workspace --no-run` built it), its output in $out/NAME.log.
measure() {
  local name=$1 bench=$2
  shift 2
  local t0=$SECONDS
  echo "--- $name: cargo bench --bench $bench"
  if timeout 900 cargo bench --workspace --locked --bench "$bench" -- "${criterion_args[@]}" "$@" \
    >"$out/$name.log" 2>&1; then
    echo "    done in $((SECONDS - t0)) s"
  else
    echo "    FAILED (exit $?) after $((SECONDS - t0)) s; last lines of $out/$name.log:"
    tail -n 15 "$out/$name.log" | sed 's/^/    /'
    failed+=("$name")
  fi
}

if [ "$table_only" != 1 ]; then
  echo "host: $(nproc) CPUs, load average $(cut -d' ' -f1-3 /proc/loadavg), $( [ "$(id -u)" = 0 ] && echo root || echo 'not root: veth rows skipped, no SCHED_FIFO'); MOTUS_REALTIME=$MOTUS_REALTIME"
  measure reaction reaction
  MOTUS_EPL_SEGMENTS=udp.1ms,udp.400us,veth.1ms measure segment monitor
  MOTUS_EPL_SECONDS="$MOTUS_EPL_POLLING_SECONDS" MOTUS_REALTIME=off MOTUS_EPL_SEGMENTS=veth.400us measure segment-polling monitor
  measure sync sync_jitter
  measure sdo canopen_rates
  measure nfv2 cycle
fi

# The rows: key | figure | op (<= lower is better, >= higher is better) | target | unit |
# today (the figure reported before, and where it comes from) | gross (optional: what counts
# as a gross regression; default 10x the target). The 1 ms miss rates have a 0.1 % target
# that a 5 s run on a shared host misses by more than 10x from noise alone (1.6 % seen on
# CI's quiet VM): their gross line is 10 % of cycles (a segment that misses one cycle in
# ten is broken, not noisy). The 1 ms jitter rows (100 us targets; 944 us seen beside other
# builds) regress grossly past 5 ms, five periods. Where the targets come from:
# - reaction: p99 below 1 ms inside Motus (the juggler's acceptance); p50 and the CPU part
#   as reported (the CPU part against the supervisor bench's 5 us evaluation target);
# - segment: 0.1 % of cycles with a missed node at 1 ms (the POWERLINK target), 5 % at
#   400 us (the limit the segment tests held); MN jitter "100 us class" (specs/powerlink.md);
# - SYNC 1 kHz: no figure was documented; 100 us (a tenth of the period) against the
#   51-91 us first measured on the 2-core dev VM;
# - where-at-t: 0.05 deg and 80 % answered (the pan-tilt acceptance, docs/decisions.md);
# - NFv2 cycle: within 10 % of the wire limit (the bench's target);
# - openPOWERLINK interop (issue 20, measured by the suite as root): no reset of the Motus CN
#   by openPOWERLINK's 1 ms MN in the hold, CN turnaround p99 below 100 us (the MN's PRes
#   time-out is 200 us), Motus MN SoC jitter p99 below 100 us. Most resets on a loaded or
#   idle-halting host are the MN's own: its cycle overruns its threshold and it resets every
#   node; their gross line is one reset a second of the 60 s hold. Resets for a lost PRes of
#   the Motus CN are told apart (target 0, gross past 10);
# - SDO: issue 5's 10x python-canopen's master, met by each master at its best and with
#   concurrent transfers; one transfer at a time the bus sets the rate and no master reaches
#   10x here (docs/decisions.md), so that row's target is the figure reported (2.6x).
rows=$(cat <<'EOF'
reaction.veth.inside.p99|reaction p99 inside Motus (veth, PRes -> revoke sent)|<=|1000|us|102-113 us (decisions.md)
reaction.veth.inside.p50|reaction p50 inside Motus (veth)|<=|64|us|61-64 us (decisions.md)
reaction.cpu.p99|reaction CPU part p99 (PRes -> revoke, no syscall)|<=|5000|ns|below the 5 us evaluation target
epl.udp.1ms.missed|1 ms cycle, UDP: cycles with a missed node|<=|0.1|%|0.05-0.2 % (decisions.md)|10
epl.veth.1ms.missed|1 ms cycle, veth: cycles with a missed node|<=|0.1|%|none reported (tests allowed 2 %)|10
epl.udp.400us.missed|400 us cycle, UDP: cycles with a missed node|<=|5|%|0.14-0.40 % (decisions.md)
epl.veth.400us.missed|400 us cycle, veth (polling): cycles with a missed node|<=|5|%|0.17 % over 60 s (decisions.md)
epl.udp.1ms.jitter.p99|1 ms POWERLINK MN cycle start jitter p99, UDP|<=|100|us|100 us class (powerlink.md)|5000
epl.veth.1ms.jitter.p99|1 ms POWERLINK MN cycle start jitter p99, veth|<=|100|us|100 us class (powerlink.md)|5000
sync.1khz.jitter.p99|1 kHz CANopen SYNC period jitter p99|<=|100|us|51-91 us (first measured here)|5000
nfv2.where.worst|where-at-t worst error, pan-tilt on real time (pty)|<=|0.05|deg|0.022-0.034 deg (decisions.md)
nfv2.where.answered|where-at-t questions answered|>=|80|%|99.5-100 % (decisions.md)
nfv2.cycle.packed.of_limit|NFv2 cycle back to back, packed, of the wire limit|<=|110|%|within 10 % (bench target)
sdo.ratio.peak|SDO rate, Motus best / python-canopen best|>=|10|x|13.6-21.3x (decisions.md)
sdo.ratio.many32|SDO rate ratio, concurrent transfers to 32 drives|>=|10|x|17.3-21.3x (decisions.md)
sdo.ratio.many8|SDO rate ratio, concurrent transfers to 8 drives|>=|10|x|8.5-10.5x (decisions.md)
sdo.ratio.one_at_a_time|SDO rate ratio, one transfer at a time|>=|2.6|x|2.6-3.4x; 10x unreachable (decisions.md)
sdo.motus.peak|SDO rate, Motus master at its best|>=|100000|/s|100-199 k/s (decisions.md)
sdo.motus.one_at_a_time|SDO rate, Motus master one transfer at a time|>=|14000|/s|14-20 k/s (decisions.md)
suite.demo_load.juggler_trips|juggler supervisor trips, demo under 250 web clients (60 s in CI)|<=|0|count|0 in 5 runs (issue 18)
suite.demo_browser.camera_fps|simulated camera frames/s received in the browser (demo)|>=|10|fps|15 drawn by the station (issue 22)
suite.demo_load.estop.p99|E-stop answer p99, demo under 250 web clients|<=|100|ms|77-97 ms (issue 18)
suite.oplk_cn_1ms.resets|openPOWERLINK MN 1 ms: resets of the Motus CN in the hold|<=|0|count|4-6 in CI unpinned; 0 in 3 local 60 s runs pinned|60
suite.oplk_cn_1ms.resets_lost_pres|of which for a lost PRes (not the MN's own overrun)|<=|0|count|1-5 a minute unpinned (decisions.md)
suite.oplk_cn_1ms.turnaround.p99|Motus CN PReq -> PRes p99 (openPOWERLINK MN, 1 ms, veth)|<=|100|us|23-25 us unpinned; 2.4-2.9 us pinned (decisions.md)
suite.oplk_mn_1ms.jitter.p99|Motus MN SoC jitter p99 (openPOWERLINK CN, 1 ms, veth)|<=|100|us|1.5-15.7 us (issue 20 branch)
EOF
)

# Figures measured by the test suite (the demo under load runs there, alone): suite.* rows.
figures=$(cat "$out"/*.log "$out"/from-suite/*.log 2>/dev/null | grep -h '^REALTIME ' || true)
skips=$(cat "$out"/*.log 2>/dev/null | grep -h '^REALTIME-SKIP ' || true)
gross=0
missing=0
table="$out/table.txt"
# The table is written to a file by this shell (not a pipeline's subshell: the counts above
# must survive), then printed.
{
  printf '%-58s | %12s | %12s | %-44s | %s\n' "figure" "measured" "target" "today" "status"
  printf '%s\n' "$(printf '%.0s-' {1..150})"
  while IFS='|' read -r key label op target unit today gross_at; do
    [ -n "$key" ] || continue
    line=$(printf '%s\n' "$figures" | awk -v k="$key" '$2 == k { v = $3 } END { if (v != "") print v }')
    if [ -z "$line" ]; then
      reason=$(printf '%s\n' "$skips" | awk -v k="$key" 'index(k, $2) == 1 { $1 = ""; $2 = ""; sub(/^ +/, ""); print; exit }')
      if [ -n "$reason" ]; then
        status="skipped ($reason)"
      elif [ "${key#suite.}" != "$key" ]; then
        status="skipped (measured by scripts/test.sh: run it first)"
      else
        status="MISSING (measurement failed)"
        missing=$((missing + 1))
      fi
      printf '%-58s | %12s | %12s | %-44s | %s\n' "$label" "-" "$op $target $unit" "$today" "$status"
      continue
    fi
    # A count whose target is 0 (trips) regresses grossly past 10.
    status=$(awk -v m="$line" -v t="$target" -v op="$op" -v gross="${gross_at:-}" 'BEGIN {
      g = (gross != "") ? gross : ((t == 0) ? 10 : 10 * t)
      if (op == "<=") { if (m <= t) s = "MET"; else if (m > g) s = "GROSS REGRESSION"; else s = "NOT MET" }
      else { if (m >= t) s = "MET"; else if (m < t / 10) s = "GROSS REGRESSION"; else s = "NOT MET" }
      print s }')
    [ "$status" = "GROSS REGRESSION" ] && gross=$((gross + 1))
    printf '%-58s | %12s | %12s | %-44s | %s\n' "$label" "$line $unit" "$op $target $unit" "$today" "$status"
  done <<<"$rows"
} >"$table"
cat "$table"
# Notes the measurements left beside their figures (e.g. why the juggler tripped).
notes=$(cat "$out"/*.log "$out"/from-suite/*.log 2>/dev/null | grep -h '^REALTIME-NOTE ' || true)
if [ -n "$notes" ]; then
  echo
  printf '%s\n' "$notes" | sed 's/^REALTIME-NOTE /note: /'
fi

echo
echo "table: $table; logs: $out/*.log"
status=0
if [ "${#failed[@]}" -gt 0 ]; then
  echo "measurements that failed to run: ${failed[*]}"
  status=1
fi
if [ "$missing" -gt 0 ]; then
  echo "$missing figure(s) missing"
  status=1
fi
if [ "$gross" -gt 0 ]; then
  echo "$gross gross regression(s): worse than 10x the target"
  status=1
fi
exit "$status"
