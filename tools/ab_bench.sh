#!/usr/bin/env bash
# Two builds of fulcrum_bench on one scene, in pairs of runs taken back to back (AB, then BA,
# ...), so that both see the same moments of a shared machine. Prints each build's fastest and
# median ms per step and the pairs' ratios B / A (median and geometric mean): below 1, B is
# faster. On this 2-core machine runs of one build spread by 5 to 20 % within minutes; the ratio
# of two runs taken together spreads less. Run nothing else meanwhile.
#
# usage: tools/ab_bench.sh A_BIN_DIR B_BIN_DIR SCENE [PAIRS=10] [STEPS=100] [THREADS=1]
#   A_BIN_DIR, B_BIN_DIR  directories holding fulcrum_bench (a copy of build/bin's will do)
#   one thread runs pinned to core 1 (taskset), two or more unpinned.
set -euo pipefail
a=${1:?usage: ab_bench.sh A_BIN_DIR B_BIN_DIR SCENE [PAIRS] [STEPS] [THREADS]}
b=${2:?usage: ab_bench.sh A_BIN_DIR B_BIN_DIR SCENE [PAIRS] [STEPS] [THREADS]}
scene=${3:?usage: ab_bench.sh A_BIN_DIR B_BIN_DIR SCENE [PAIRS] [STEPS] [THREADS]}
pairs=${4:-10}
steps=${5:-100}
threads=${6:-1}
pin=()
[ "$threads" = 1 ] && command -v taskset > /dev/null && pin=(taskset -c 1)

run() {  # bin dir -> ms per step of one run
  "${pin[@]}" "$1/fulcrum_bench" --scene "$scene" --repeats 1 --steps "$steps" \
    --threads "$threads" | awk -F'|' -v s="$scene" '$2 ~ "^ *"s" *$" {gsub(/ /, "", $5); print $5}'
}

out=$(mktemp)
trap 'rm -f "$out"' EXIT
for i in $(seq "$pairs"); do
  if [ $((i % 2)) = 1 ]; then
    x=$(run "$a")
    y=$(run "$b")
  else
    y=$(run "$b")
    x=$(run "$a")
  fi
  echo "$x $y" >> "$out"
done
python3 - "$out" "$scene" "$pairs" << 'EOF'
import math, statistics, sys
rows = [tuple(map(float, line.split())) for line in open(sys.argv[1])]
a = [r[0] for r in rows]
b = [r[1] for r in rows]
q = [y / x for x, y in rows]
g = math.exp(sum(map(math.log, q)) / len(q))
print(f"{sys.argv[2]}, {sys.argv[3]} pairs: A fastest {min(a):.3f} median {statistics.median(a):.3f}"
      f" | B fastest {min(b):.3f} median {statistics.median(b):.3f}"
      f" | B/A median {statistics.median(q):.4f}, geometric mean {g:.4f}")
EOF
