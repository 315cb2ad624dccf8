#!/usr/bin/env bash
# Are two versions of pfslam's answers byte-identical? Runs the same commands with each source
# tree (the demo, slam on Intel, FR079 and the Mines rover with default settings, localize on a
# simulated log) and compares the trajectories and maps.
#
#   git worktree add ../before <REV>   (or a clone)
#   bench/process/same_outputs.sh ../before/src src /tmp/same
#
# Needs the recordings in ../shared/data (or PFSLAM_DATA). Takes about 2 minutes per tree.
set -euo pipefail
before=$(realpath "$1"); after=$(realpath "$2"); work=${3:-/tmp/pfslam-same}
data=${PFSLAM_DATA:-$(dirname "$(realpath "$0")")/../../../shared/data}
py=${PYTHON:-python}
run() {  # run SRC OUT
  local src=$1 d=$2
  mkdir -p "$d"
  export PYTHONPATH=$src
  $py -m pfslam.cli demo -o "$d/demo" > "$d/demo.txt" 2>&1
  $py -m pfslam.cli slam "$data/carmen/intel.gfs.log.gz" --odometry synthetic:0 -o "$d/intel" > "$d/intel.txt" 2>&1
  $py -m pfslam.cli slam "$data/carmen/fr079.gfs.log.gz" --odometry synthetic:0 -o "$d/fr079" > "$d/fr079.txt" 2>&1
  $py -m pfslam.cli slam "$data/mines/exp2.dat" -o "$d/mines" > "$d/mines.txt" 2>&1
  $py -m pfslam.cli simulate -o "$d/sim" --duration 60 --seed 3 > "$d/sim.txt" 2>&1
  $py -m pfslam.cli localize "$d/sim/train_lidar0.mat" --joint "$d/sim/train_joint0.mat" --map "$d/sim/map.yaml" \
    -o "$d/loc" > "$d/loc.txt" 2>&1
}
run "$before" "$work/before"
run "$after" "$work/after"
status=0
for d in demo intel fr079 mines loc; do
  for f in trajectory.tum odometry.tum map.pgm map.yaml reference.tum covariance.csv; do
    [ -f "$work/before/$d/$f" ] || continue
    if cmp -s "$work/before/$d/$f" "$work/after/$d/$f"; then echo "same     $d/$f"; else echo "DIFFERS  $d/$f"; status=1; fi
  done
done
exit $status
