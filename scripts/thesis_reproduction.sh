#!/usr/bin/env bash
# The thesis's sweeps (Tables 2-7) on thesis-style scenes of the built-in cap with the thesis
# preset, Table 7 also with binpose's default preset and on a second part (IPD obj_000000), then
# the tables of docs/thesis_reproduction.md. Results in out/thesis/.
#   scripts/thesis_reproduction.sh [SCENES for Tables 2-6, default 5]
set -euo pipefail
cd "$(dirname "$0")/.."
scenes=${1:-5}
out=out/thesis
bin=build/binpose
mkdir -p "$out"
sweep() { local name=$1; shift; echo "== $name"; $bin sweep --thesis-scenes --instances 16 --seed 200 "$@" --out "$out/$name" > "$out/$name.log"; }
r="20,22.5,25,27.5,30"
sweep table7 --scenes 10 --preset thesis --r $r --rho-sub 0.06,0.07,0.08,0.09
sweep table7_default --scenes 10 --preset default --r $r --rho-sub 0.06,0.07,0.08,0.09
ipd=../shared/data/ipd_parts/models/obj_000000.ply
sweep ipd0_thesis --scenes 10 --preset thesis --model $ipd --r 42.75 --rho-sub 0.0205  # Table 7 middle, scaled to 102.6 mm
sweep ipd0_default --scenes 10 --preset default --model $ipd --r 42.75 --rho-sub 0.0205
# Tables 2-6: each table's swept and fixed values (the thesis's), with the thesis preset and
# again with binpose's default preset.
declare -A table=(
  [2]="--r $r --rho-sub 0.06 --e-gmax 1,1.5,2,2.5,3 --eta 20 --c-n 9"
  [3]="--r $r --rho-sub 0.06 --e-gmax 1.75 --c-n 6,7,8,9,10,11,12 --eta 20"
  [4]="--r 15,17.5,20,22.5,25,27.5,30 --rho-sub 0.06 --e-gmax 1.75 --eta 5,10,15,20,25 --c-n 9"
  [5]="--r $r --rho-sub 0.05 --e-gmax 1.5 --eta 15 --c-n 8 --d-dist 0.5,0.6,0.7,0.8,0.9,1.0,1.1,1.2"
  [6]="--r $r --rho-sub 0.05 --e-gmax 1.5 --eta 15 --c-n 8 --overlap 0,0.15,0.25,0.35"
)
for t in 2 3 4 5 6; do
  # shellcheck disable=SC2086  # the values are words
  sweep "table$t" --scenes "$scenes" --preset thesis ${table[$t]}
  sweep "table${t}_default" --scenes "$scenes" --preset default ${table[$t]}
done
/usr/bin/env python3 scripts/thesis_tables.py "$out"/table7 "$out"/table7:r "$out"/table7:rho_sub "$out"/table7_default:r \
  "$out"/ipd0_thesis "$out"/ipd0_default "$out"/table2:e_gmax "$out"/table3:C_n "$out"/table4:eta "$out"/table4:r \
  "$out"/table5:d_dist "$out"/table6:p_d "$out"/table2_default:e_gmax "$out"/table3_default:C_n \
  "$out"/table4_default:eta "$out"/table5_default:d_dist "$out"/table6_default:p_d > "$out/tables.md"
echo "tables: $out/tables.md"
