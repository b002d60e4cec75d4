#!/usr/bin/env bash
# The layers of src/gcmap point one way: a folder includes only itself and the folders of lower
# layers below. Prints every include that points up and exits 1 if there is one (a CTest test).
set -euo pipefail
cd "$(dirname "$0")/../src/gcmap"

declare -A layer=(
  [core]=0
  [io]=1 [registration]=1 [eval]=1
  [graph]=2
  [cuda]=3 [sim]=3
  [odometry]=4 [loop]=4 [calibration]=4
  [mapping]=5
  [session]=6
  [viz]=7
)

bad=0
for dir in */; do
  dir=${dir%/}
  [[ -n "${layer[$dir]+x}" ]] || { echo "src/gcmap/$dir: folder has no layer in scripts/check_layers.sh"; bad=1; continue; }
  while IFS=: read -r file line target; do
    [[ "$target" == "$dir" ]] && continue
    if [[ -z "${layer[$target]+x}" || ${layer[$target]} -ge ${layer[$dir]} ]]; then
      echo "src/gcmap/$file:$line: $dir (layer ${layer[$dir]}) includes $target (layer ${layer[$target]:-none})"
      bad=1
    fi
  done < <(grep -rnoE '#include "gcmap/[a-z_]+/' "$dir" | sed -E 's#^([^:]+):([0-9]+):\#include "gcmap/([a-z_]+)/#\1:\2:\3#')
done
if ((bad)); then echo "layer check: includes point up (see above)"; exit 1; fi
echo "layer check: every include points down"
