#!/usr/bin/env bash
# Writes the static and modal outputs of the cantilever on 2 ranks and opens them in ParaView.
set -euo pipefail
flexopt="$1"; src="$2"; out="$3"
rm -rf "$out"
mpirun -n 2 "$flexopt" simulate "$src/cases/cantilever" --out "$out/static"
mpirun -n 2 "$flexopt" modes "$src/cases/beam_modes" --count 4 --out "$out/modes"
pvpython --force-offscreen-rendering "$src/tests/paraview_open.py" "$out/static" static
pvpython --force-offscreen-rendering "$src/tests/paraview_open.py" "$out/modes" modes
