#!/bin/bash
# Runs every shipped deck under `mpirun -np N` for a few steps (peridot run --max-steps) and
# prints one line per deck and rank count: its exit status and the first error line. The check
# behind "every shipped deck runs on N ranks" (issue 26); not part of CI, since the paper-size
# decks' set-up alone takes minutes on two cores.
#   tools/sweep_decks_on_ranks.sh [peridot binary] [steps] [rank counts...]
# Defaults: build/ci/apps/peridot/peridot, 2 steps, ranks 2 and 4. Outputs go to a temporary
# folder that is removed as it goes; each run is bounded by `timeout` (300 s).
set -u
# OpenMPI refuses root unless told (containers, CI machines).
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
root=$(cd "$(dirname "$0")/.." && pwd)
exe=${1:-$root/build/ci/apps/peridot/peridot}
steps=${2:-2}
shift $(( $# > 2 ? 2 : $# ))
ranks=("$@")
[ ${#ranks[@]} -eq 0 ] && ranks=(2 4)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failed=0
for deck in "$root"/data/decks/*.yaml "$root"/data/decks/*/*.yaml; do
  name=${deck#"$root"/data/decks/}
  for n in "${ranks[@]}"; do
    start=$(date +%s.%N)
    timeout -k 5 300 mpirun --oversubscribe --mca mpi_yield_when_idle 1 -np "$n" "$exe" run "$deck" --out "$work/out" --threads 1 --max-steps "$steps" --quiet > "$work/log" 2>&1
    code=$?
    printf '%-48s np %-2s exit %-3s %7.1f s  %s\n' "$name" "$n" "$code" "$(echo "$(date +%s.%N) - $start" | bc)" "$(grep -m1 'error' "$work/log" | cut -c1-160)"
    [ "$code" -ne 0 ] && failed=$((failed + 1))
    rm -rf "$work/out"
  done
done
echo "$failed runs failed"
[ "$failed" -eq 0 ]
