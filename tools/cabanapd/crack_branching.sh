#!/usr/bin/env bash
# Crack branching (seed 000 Sec. 6.1) in Peridot and in CabanaPD, one after the other on the same
# cores and thread count, each run ROUNDS times in turn: each code's time-loop s/step with no
# output, and peak RSS. Peridot runs peridot-bench (its own run loop, every output off) on the
# lattice stencil, on the bond list in single precision (the default) and in double; CabanaPD
# runs its crack-branching example cut to the same steps, with output off after step 0.
#
# usage: tools/cabanapd/crack_branching.sh CABANAPD_EXE CABANAPD_JSON [WORK_DIR]
#   CABANAPD_EXE   CabanaPD's CrackBranching example, built outside this repository
#                  (its examples/mechanics/crack_branching.cpp)
#   CABANAPD_JSON  its input, examples/mechanics/inputs/crack_branching.json (400 x 160 x 8 cells)
#   WORK_DIR       default /tmp/peridot_cb_vs_cabanapd
# env: THREADS (default 2), STEPS (default 100), ROUNDS (default 2), SIZES ("64k 512k"),
#      BENCH (default build/ci/apps/peridot-bench/peridot-bench; build/release/... for README command 1's preset).
# 64k is CabanaPD's input coarsened 2x (200 x 80 x 4 cells, delta 2 mm), as data/decks/crack_branching_3d.yaml;
# 512k is its input unchanged, as data/decks/crack_branching_3d_fine.yaml.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cabanapd_args /tmp/peridot_cb_vs_cabanapd 2,17p "$@"
steps=${STEPS:-100}
rounds=${ROUNDS:-2}
sizes=${SIZES:-64k 512k}
bench=$(readlink -f "${BENCH:-$repo/build/ci/apps/peridot-bench/peridot-bench}")
for f in "$cabana_exe" "$bench"; do [[ -x $f ]] || { echo "error: not an executable: $f" >&2; exit 2; }; done
[[ -f $cabana_json ]] || { echo "error: no such file: $cabana_json" >&2; exit 2; }
[[ $steps =~ ^[0-9]+$ && $steps -ge 1 && $steps -le 955 ]] || { echo "error: STEPS = '$steps': allowed 1 to 955" >&2; exit 2; }
mkdir -p "$work"
unset OMP_PROC_BIND OMP_PLACES
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; $threads threads each; $steps steps; bench $bench"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"


# CabanaPD's input for a size, cut to $steps steps of its 4.5e-8 s, output only at step 0.
cabana_input() {
  python3 - "$cabana_json" "$1" "$steps" "$2" << 'EOF'
import json, sys
src, size, steps, out = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
d = json.load(open(src))
if size == "64k":
    d["num_cells"]["value"] = [200, 80, 4]
    d["horizon"]["value"] = 0.002
d["final_time"]["value"] = (steps + 0.5) * d["timestep"]["value"]  # it runs int(final_time / timestep) steps
d["output_frequency"]["value"] = steps + 1
json.dump(d, open(out, "w"), indent=1)
EOF
}

run_cabana() {  # size round
  local dir="$work/cabanapd_$1_$2"
  rm -rf "$dir" && mkdir -p "$dir"
  cabana_input "$1" "$dir/input.json"
  (cd "$dir" && OMP_NUM_THREADS=$threads OMP_PROC_BIND=spread OMP_PLACES=threads /usr/bin/time -v -o time.log "$cabana_exe" input.json > stdout.log 2>&1)
  # Its time loop in all (force, neighbours, energy, integration), over the steps it ran.
  local rate total
  total=$(awk '/PERFORMANCE/ {print $4}' "$dir/cabanaPD.out" | tail -1)
  rate=$(awk '/^#Steps\/s/ {getline; print $1}' "$dir/cabanaPD.out" | tail -1)
  [[ -n $total && -n $rate ]] || { echo "error: no PERFORMANCE or Steps/s line in $dir/cabanaPD.out" >&2; exit 1; }
  printf '%-28s %6s %10s %8s\n' "CabanaPD" "$1" "$(awk -v r="$rate" 'BEGIN {printf "%.4f", 1 / r}')" "$(peak_mib "$dir/time.log")"
  rm -f "$dir"/particles_*.h5 "$dir"/particles_*.xmf
}

run_peridot() {  # size bonds precision
  local deck="$repo/data/decks/crack_branching_3d.yaml" out
  [[ $1 == 512k ]] && deck="$repo/data/decks/crack_branching_3d_fine.yaml"
  out=$("$bench" "$deck" --threads "$threads" --steps "$steps" --bonds "$2" --list-precision "$3" 2>&1)
  local s mib
  s=$(grep -o 'threads [0-9]*: [0-9.e+-]* s/step' <<< "$out" | awk '{print $3}')
  mib=$(grep -o 'peak RSS [0-9]* MiB' <<< "$out" | awk '{print $3}')
  local name="Peridot $2"
  [[ $2 == list ]] && name="Peridot list, $3"
  printf '%-28s %6s %10s %8s\n' "$name" "$1" "$s" "$mib"
}

printf '\n%-28s %6s %10s %8s\n' code size "s/step" "peak MiB"
for size in $sizes; do
  for round in $(seq 1 "$rounds"); do
    run_cabana "$size" "$round"
    run_peridot "$size" stencil single
    run_peridot "$size" list single
    run_peridot "$size" list double
  done
done
echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
