#!/usr/bin/env bash
# S3 from random weights across seeds, peak learning rates and crop sizes:
# small RAFT-Stereo and IGEV-Stereo (sizes that train on 2 CPU cores in a
# few minutes) on a small synthetic set, 120 steps each; held-out Out-3 ALL
# of the teacher before and after, and whether the run learned (after <=
# 0.6 x before). Prints a Markdown table (BENCHMARKS.md, "S3 robustness").
# Both networks are validated at the 3 iterations they train with: from
# random weights, more iterations of an update than it was trained for can
# diverge (docs/training.md, "S3 from random weights").
#
#   bash tools/bench/s3_robustness.sh [MBS_TOOL] [OUT_DIR] [-- EXTRA --set FLAGS...]
#
# MBS_TOOL defaults to target/release/mbs-tool; extra flags after `--` go to
# every run (e.g. `-- --set trainer.geometry_start=0 --set
# trainer.geometry_warmup=0 --set trainer.loss.range_weight=0 --set
# trainer.loss.out_of_view_invalid=false --set
# trainer.loss.geometry_scale_match=false --set
# trainer.loss.outside_mask_weight=0 --set trainer.loss.view_weight=0
# --set trainer.lr.pct_start=0.01` for the paper's plain loss and
# schedule).
set -euo pipefail
tool=${1:-target/release/mbs-tool}
out=${2:-s3-robustness}
shift $(( $# >= 2 ? 2 : $# ))
[ "${1:-}" = "--" ] && shift
extra=("$@")
mkdir -p "$out"
if [ ! -f "$out/data/manifest.json" ]; then
    "$tool" synth --out "$out/data" --seed 13 --frames 6 --towns Town01,Town10 \
        --weathers ClearNoon --width 192 --height 96 --focal 96 --no-checksums > /dev/null 2>&1
fi
network() {
    case $1 in
    raft-stereo) echo --set network.raft_stereo.hidden_dim=24 --set network.raft_stereo.gru_levels=2 \
        --set network.raft_stereo.n_downsample=3 --set network.raft_stereo.train_iters=3 \
        --set network.raft_stereo.test_iters=3 ;;
    igev) echo --set network.igev.hidden_dim=24 --set network.igev.gru_levels=2 \
        --set network.igev.corr_radius=3 --set network.igev.max_disp=64 \
        --set network.igev.train_iters=3 --set network.igev.test_iters=3 ;;
    esac
}
out3() { python3 -c "import json,sys; l=[json.loads(x) for x in open(sys.argv[1])]; print(l[int(sys.argv[2])]['ALL']['out3'])" "$@"; }
echo "| network | peak LR | crop | seed | Out-3 ALL untrained | Out-3 ALL after 120 steps | ratio | learned |"
echo "| --- | --- | --- | --- | --- | --- | --- | --- |"
for backbone in raft-stereo igev; do
    for lr in 0.0002 0.001; do
        for crop in 64x160 48x128; do
            for seed in 21 8 5; do
                run="$out/$backbone-$lr-$crop-$seed"
                if [ ! -f "$run/val.jsonl" ] || [ "$(wc -l < "$run/val.jsonl")" -lt 2 ]; then
                    # shellcheck disable=SC2046
                    "$tool" train "$out/data/manifest.json" --out "$run" --restart --backbone "$backbone" \
                        --steps 120 --batch-size 2 --crop "$crop" --max-disparity 48 --val-every 120 \
                        --lr "$lr" --seed "$seed" --set trainer.ema_base=0.9 \
                        --set augment.occlusion_min_side=10 --set augment.occlusion_max_side=30 \
                        $(network "$backbone") "${extra[@]}" > "$run.log" 2>&1 || true
                fi
                before=$(out3 "$run/val.jsonl" 0 2> /dev/null || echo nan)
                after=$(out3 "$run/val.jsonl" -1 2> /dev/null || echo nan)
                python3 -c "
import math, sys
b, a = float(sys.argv[5]), float(sys.argv[6])
r = a / b if b > 0 else math.nan
ok = 'yes' if r <= 0.6 else 'NO'
print(f'| {sys.argv[1]} | {sys.argv[2]} | {sys.argv[3]} | {sys.argv[4]} | {b:.1f} % | {a:.1f} % | {r:.2f} | {ok} |')
" "$backbone" "$lr" "$crop" "$seed" "$before" "$after"
            done
        done
    done
done
