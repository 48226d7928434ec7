#!/usr/bin/env bash
# Kalthoff-Winkler in Peridot and in CabanaPD, one after the other on the same cores and thread
# count: whole-process wall time and peak RSS (/usr/bin/time), each code's own time-loop
# s/step, and the crack of each measured the same way (kw_crack.py: angle to the notch, reach,
# mean point damage).
#
# usage: tools/cabanapd/kalthoff_winkler.sh CABANAPD_EXE CABANAPD_JSON [WORK_DIR]
#   CABANAPD_EXE   CabanaPD's KalthoffWinkler example, built outside this repository
#                  (its examples/mechanics/kalthoff_winkler.cpp)
#   CABANAPD_JSON  its input, examples/mechanics/inputs/kalthoff_winkler.json
#   WORK_DIR       default /tmp/peridot_kw_vs_cabanapd (outputs of both; CabanaPD's take ~5 GB)
# env: THREADS (default 2), PERIDOT (default build/ci/apps/peridot/peridot),
#      DECK (default data/decks/kalthoff_winkler_cabanapd.yaml, CabanaPD's bulk modulus), SKIP_CABANAPD=1 to re-measure Peridot only.
# Needs h5dump (Debian hdf5-tools) to read CabanaPD's HDF5 output.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
cabanapd_args /tmp/peridot_kw_vs_cabanapd 2,16p "$@"
peridot=$(readlink -f "${PERIDOT:-$repo/build/ci/apps/peridot/peridot}")
deck=$(readlink -f "${DECK:-$repo/data/decks/kalthoff_winkler_cabanapd.yaml}")
for f in "$cabana_exe" "$peridot"; do [[ -x $f ]] || { echo "error: not an executable: $f" >&2; exit 2; }; done
for f in "$cabana_json" "$deck"; do [[ -f $f ]] || { echo "error: no such file: $f" >&2; exit 2; }; done
command -v h5dump > /dev/null || { echo "error: h5dump not found (apt-get install hdf5-tools)" >&2; exit 2; }
mkdir -p "$work/peridot" "$work/cabanapd"
# Peridot takes --threads and no binding: with OMP_PROC_BIND set, the GCC OpenMP runtime its
# SuiteSparse and PETSc load pins it to one core (peridot warns). CabanaPD gets Kokkos's binding.
unset OMP_PROC_BIND OMP_PLACES
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs), $(nproc) cores; $threads threads each"
echo "load before: $(cut -d' ' -f1-3 /proc/loadavg)"

wall_s() { awk -F': ' '/Elapsed \(wall clock\)/ {n = split($2, t, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; print s}' "$1"; }

echo "== Peridot: $deck"
rm -rf "$work/peridot/out"
/usr/bin/time -v -o "$work/peridot/time.log" "$peridot" run "$deck" --out "$work/peridot/out" --threads "$threads" > "$work/peridot/stdout.log" 2>&1
p_loop=$(grep -m1 -o 'done: [0-9]* steps in [0-9.]* s ([0-9.e+-]* s/step' "$work/peridot/stdout.log" | sed 's/.*(//; s/ s\/step//')
p_vtu=$(ls "$work/peridot/out"/*.vtu | sort | tail -1)

if [[ ${SKIP_CABANAPD:-0} != 1 ]]; then
  echo "== CabanaPD: $cabana_exe $cabana_json"
  (cd "$work/cabanapd" && rm -f cabanaPD.out particles_*.h5 particles_*.xmf &&
   OMP_NUM_THREADS=$threads OMP_PROC_BIND=spread OMP_PLACES=threads /usr/bin/time -v -o time.log "$cabana_exe" "$cabana_json" > stdout.log 2>&1)
fi
# The summary line after the last step: "#Procs Particles | Total Force ..." then "1 N | total force ...".
c_steps=$(grep -E '^[0-9]+/[0-9]+ ' "$work/cabanapd/cabanaPD.out" | tail -1 | cut -d/ -f1)
c_total=$(awk '/PERFORMANCE/ {print $4}' "$work/cabanapd/cabanaPD.out" | tail -1)
c_loop=$(awk -v t="$c_total" -v n="$c_steps" 'BEGIN {printf "%.4g", t / n}')
c_h5=$(ls -v "$work/cabanapd"/particles_*.h5 | tail -1)

echo "load after: $(cut -d' ' -f1-3 /proc/loadavg)"
printf '\n%-10s %14s %12s %14s\n' code "loop s/step" "wall [s]" "peak RSS MiB"
printf '%-10s %14s %12s %14s\n' Peridot "$p_loop" "$(wall_s "$work/peridot/time.log")" "$(peak_mib "$work/peridot/time.log")"
printf '%-10s %14s %12s %14s\n' CabanaPD "$c_loop" "$(wall_s "$work/cabanapd/time.log")" "$(peak_mib "$work/cabanapd/time.log")"
echo
python3 "$here/kw_crack.py" "$p_vtu"
python3 "$here/kw_crack.py" "$c_h5"
