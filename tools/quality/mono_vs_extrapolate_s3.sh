#!/usr/bin/env bash
# Issue 60's quality report (docs/quality.md, "S3 from single photos
# against S3 from real pairs"): S3 from random weights trained only on sets
# `mono` makes from single photos (FastDepth), beside the same run on sets
# `extrapolate` makes from the real stereo pairs of the same photos, both
# scored on real held-out pairs with ground truth (Middlebury Teddy and
# Tsukuba, never trained on).
#
#   bash tools/quality/mono_vs_extrapolate_s3.sh SHARED_DATA FASTDEPTH_ONNX [MBS_TOOL] [OUT]
#
# SHARED_DATA: the team's real data folder (middlebury-baby2, -bowling2,
# -laundry, -teddy, -tsukuba-row3; its README.md). FASTDEPTH_ONNX:
# fastdepth_7.onnx (bash tools/setup-depth-model.sh puts it in .models/).
# MBS_TOOL defaults to target/debug/mbs-tool (the dev profile is optimised:
# cargo build -p mbs-tool), OUT to mono-vs-extrapolate-s3. ONNX Runtime is
# found through $ORT_DYLIB_PATH, else installed by tools/setup-ort.sh. The
# helper tools/quality/mono_vs_extrapolate_s3.py needs numpy and Pillow
# ($PYTHON, default python3). SEEDS (default "1 2 3 4 5") and STEPS (2000)
# change the runs; ARMS (default "mono ext") the training sets: mono
# (FastDepth, the real pairs' disparity range), ext (extrapolate) and
# monodef (mono with its default range, 5-15 % of the width). Every step
# skips what is already there, so a killed run is finished by running it
# again. Prints the Markdown tables at the end (the defaults: about 20
# minutes on 2 shared cores). The report's second table is SEEDS="1 2 3"
# STEPS=600 ARMS="mono ext monodef" into another OUT (about 6 minutes).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
shared=${1:?usage: $0 SHARED_DATA FASTDEPTH_ONNX [MBS_TOOL] [OUT]}
model=${2:?usage: $0 SHARED_DATA FASTDEPTH_ONNX [MBS_TOOL] [OUT]}
tool=${3:-$root/target/debug/mbs-tool}
out=${4:-mono-vs-extrapolate-s3}
py=${PYTHON:-python3}
seeds=${SEEDS:-1 2 3 4 5}
steps=${STEPS:-2000}
arms=${ARMS:-mono ext}
export ARMS=$arms
every=$((steps / 4))
if [ -z "${ORT_DYLIB_PATH:-}" ]; then
    ORT_DYLIB_PATH=$(bash "$root/tools/setup-ort.sh" | tail -1)
    export ORT_DYLIB_PATH
fi
mkdir -p "$out/eval" "$out/runs"
data=$out/data

# 1. The training pairs (Baby2, Bowling2, Laundry: views k and k+1, k = 0..5,
#    half size) and the held-out pairs (Teddy im2/im6 at half size, Tsukuba
#    col3/col4 at full size) with their ground truth as PFM.
[ -f "$data/heldout/tsukuba/gt.pfm" ] || "$py" "$here/mono_vs_extrapolate_s3.py" prep "$shared" "$data"

# 2. The two training sets, 18 four-view samples each, the photo (the pair's
#    left view) as camera 1 in both. mono: one baseline's largest disparity
#    drawn per photo in 3-4.5 % of the width, the real pairs' one-step range
#    at this size (Baby2 3.1 %, Bowling2 3.7 %, Laundry 4.3 % from their
#    ground truth), so that both sets train the same disparity range.
#    extrapolate: the built-in matcher on the real pair, its defaults.
[ -f "$data/mono/manifest.json" ] || "$tool" mono --images "$data/src/image_2" --model "$model" \
    --card fastdepth --max-disparity 0.03:0.045 --seed 0 --preview --out "$data/mono"
case " $arms " in *" monodef "*)
    [ -f "$data/monodef/manifest.json" ] || "$tool" mono --images "$data/src/image_2" --model "$model" \
        --card fastdepth --seed 0 --preview --out "$data/monodef" ;;
esac
[ -f "$data/ext/manifest.json" ] || "$tool" extrapolate --kitti "$data/src" --preview --out "$data/ext"

# 3. S3 from random weights, the compact network, the same settings and
#    seeds for both sets; the held-out pairs are never seen (validation is
#    off: the manifests hold no held-out sample). A 2-step run at a peak LR
#    of 1e-12 per seed is the untrained network (its teacher moves by about
#    1e-12 per weight), the floor.
train_flags=(--batch-size 4 --crop 64x160 --max-disparity 48 --lr 0.002
    --set trainer.lr.pct_start=0.1 --set trainer.ema_base=0.9
    --set augment.occlusion_min_side=10 --set augment.occlusion_max_side=30
    --set keep_checkpoints=8 --set log_every=10 --val-every 100000)
for seed in $seeds; do
    run=$out/runs/floor-s$seed
    [ -d "$run/checkpoints/step-0000002" ] || "$tool" train "$data/ext/manifest.json" --out "$run" --restart \
        "${train_flags[@]}" --steps 2 --checkpoint-every 2 --seed "$seed" --set trainer.lr.max_lr=1e-12 > "$run.log" 2>&1 \
        || { tail -5 "$run.log"; exit 1; }
    for arm in $arms; do
        run=$out/runs/$arm-s$seed
        last=$run/checkpoints/step-$(printf %07d "$steps")
        [ -d "$last" ] || "$tool" train "$data/$arm/manifest.json" --out "$run" \
            "${train_flags[@]}" --steps "$steps" --checkpoint-every "$every" --seed "$seed" > "$run.log" 2>&1 \
            || { tail -5 "$run.log"; exit 1; }
    done
done

# 4. Scores: every checkpoint's teacher on both held-out pairs, the S3
#    paper's protocol (stereo_toolbox: 0 < gt < 191, per image), and the
#    built-in matcher (SGM, no training) as a classical reference.
score() { # NAME PAIR [SOURCE FLAGS...]
    local name=$1 pair=$2
    shift 2
    local file=$out/eval/$name.$pair.json
    [ -s "$file" ] || "$tool" eval "$@" --left "$data/heldout/$pair/left.png" \
        --right "$data/heldout/$pair/right.png" --gt "$data/heldout/$pair/gt.pfm" \
        --protocol s3 --json > "$file" 2> "$file.log" \
        || { cat "$file.log"; rm -f "$file"; exit 1; }
}
for pair in teddy tsukuba; do
    score sgm "$pair" --max-disparity 48
    for seed in $seeds; do
        score "floor-s$seed-0" "$pair" --checkpoint "$out/runs/floor-s$seed/checkpoints/step-0000002"
        for arm in $arms; do
            for step in $(seq "$every" "$every" "$steps"); do
                score "$arm-s$seed-$step" "$pair" \
                    --checkpoint "$out/runs/$arm-s$seed/checkpoints/step-$(printf %07d "$step")"
            done
        done
    done
done
"$py" "$here/mono_vs_extrapolate_s3.py" table "$out"
