#!/usr/bin/env bash
# Point vs Gaussian LSTM on the real 3-robot data (seeds 0-4): train on 75 % of Train.csv, select
# and stop early on Val.csv, report on the held-out 25 % (never used to train or select) and on
# Val. Run from the repository root; about 3-8 min a training on one free core.
set -euo pipefail
REAL=${REAL:-../shared/reference-data/ReTLo/Datasets/3Robots}
R=results/retlo_uncertainty
python $R/split.py "$REAL/Train.csv" $R/data
for seed in 0 1 2 3 4; do
  for unc in none gaussian; do
    name=$([ $unc = none ] && echo point || echo gauss)_s$seed
    macrostate-mj train retlo --model lstm --train $R/data/kept.csv --val "$REAL/Val.csv" \
      --seed $seed --uncertainty $unc --out $R/models/$name.pt --overwrite
    for set in held val; do
      data=$([ $set = held ] && echo $R/data/held.csv || echo "$REAL/Val.csv")
      macrostate-mj evaluate retlo --model $R/models/$name.pt --data "$data" \
        --out $R/reports/${name}_$set.json --overwrite
    done
  done
done
for set in held val; do     # the five Gaussian seeds as one deep ensemble
  data=$([ $set = held ] && echo $R/data/held.csv || echo "$REAL/Val.csv")
  macrostate-mj evaluate retlo $(for s in 0 1 2 3 4; do echo --model $R/models/gauss_s$s.pt; done) \
    --data "$data" --out $R/reports/ensemble_$set.json --overwrite
done
python $R/summary.py $R/reports > $R/summary.json
