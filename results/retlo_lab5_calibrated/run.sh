#!/usr/bin/env bash
# Gaussian ReTLo trained on lab 3-robot chains (results/retlo_lab_gaussian), its uncertainty then
# refitted (`calibrate retlo`, weights unchanged) on a separate 5-robot lab collection (seed 3),
# and both scored on the lab 5-robot test chains (seed 2) that nothing was fitted on. Run from
# the repository root; the training is the long part (about 20 min on two busy cores).
set -euo pipefail
R=results/retlo_lab5_calibrated
G=results/retlo_lab_gaussian
[ -f data/lab3/Train.csv ] || macrostate-mj collect --scenario lab --robots 3 --minutes 100 \
  --seed 31 --split 80/20/0 --out data/lab3
[ -f data/lab5/instances.csv ] || macrostate-mj collect --scenario lab --robots 5 --minutes 70 \
  --seed 2 --out data/lab5
macrostate-mj experiment retlo --uncertainty gaussian --train data/lab3/Train.csv \
  --val data/lab3/Val.csv --folds 0 --test data/lab5/instances.csv --out $G --overwrite
[ -f data/lab5_val/instances.csv ] || macrostate-mj collect --scenario lab --robots 5 \
  --minutes 30 --seed 3 --out data/lab5_val
for seed in 0 1 2 3 4; do
  macrostate-mj calibrate retlo --model $G/models/lstm_seed$seed.pt \
    --val data/lab5_val/instances.csv --out $R/models/lstm_seed$seed.pt --overwrite
  for who in trained refitted; do
    model=$([ $who = trained ] && echo $G || echo $R)/models/lstm_seed$seed.pt
    macrostate-mj evaluate retlo --model $model --data data/lab5/instances.csv \
      --out $R/reports/${who}_s$seed.json --overwrite
  done
done
python $R/summary.py $R/reports > $R/summary.json
