#!/usr/bin/env bash
# Step time of one process against 2 MPI ranks at the same global batch.
# usage: bench.sh MBS_TOOL DATA_MANIFEST OUTDIR
set -euo pipefail
tool=$1; manifest=$2; out=$3
compact=(--steps 30 --batch-size 4 --crop 64x160 --max-disparity 48 --val-every 1000 --set log_every=1)
raft=(--steps 12 --batch-size 2 --crop 64x160 --max-disparity 48 --val-every 1000 --set log_every=1
  --backbone raft-stereo --set network.raft_stereo.hidden_dim=24 --set network.raft_stereo.gru_levels=2
  --set network.raft_stereo.n_downsample=3 --set network.raft_stereo.train_iters=3 --set network.raft_stereo.test_iters=6)
root=""; [ "$(id -u)" -eq 0 ] && root="--allow-run-as-root"
median() { python3 -c "import json,sys,statistics; v=[json.loads(l)['samples_per_s'] for l in open(sys.argv[1])][3:]; print(f'{statistics.median(v):.2f} samples/s, {1000*int(sys.argv[2])/statistics.median(v):.0f} ms/step')" "$1" "$2"; }
for net in compact raft; do
  declare -n args=$net
  batch=$( [ $net = compact ] && echo 4 || echo 2 )
  rm -rf "$out/$net-1" "$out/$net-2"
  "$tool" train "$manifest" --out "$out/$net-1" "${args[@]}" --jobs 2 > /dev/null 2>&1
  mpirun $root -np 2 --oversubscribe "$tool" train "$manifest" --out "$out/$net-2" "${args[@]}" --jobs 1 > /dev/null 2>&1
  echo "$net, 1 process (2 threads): $(median "$out/$net-1/train.jsonl" $batch)"
  echo "$net, 2 ranks (1 thread each): $(median "$out/$net-2/train.jsonl" $batch)"
done
