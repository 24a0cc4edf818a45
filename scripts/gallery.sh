#!/usr/bin/env bash
# Regenerates the book gallery (docs/src/gallery/*.png) with the release binary: the plots as
# the commands write them, downscaled to 760 px and a 256-colour palette. Needs Pillow (pip install pillow).
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/.." && pwd)
S=$ROOT/target/release/servo
W=$(mktemp -d)
cd $W
$S frf --loop open --out-dir frf > /dev/null
$S budget --sweep --out-dir budget > /dev/null
$S stiffness --kas 0,0.5,1,4 --out-dir stiffness > /dev/null
$S machine --no-record --out-dir machine -q > /dev/null
$S machine --no-record --flat-blank --repetitive --out-dir repetitive > /dev/null
$S toolpath -c $ROOT/examples/prescriptions/cut-gentle.toml --out-dir toolpath > /dev/null
$S study $ROOT/examples/studies/moving_mass.toml --out-dir moving_mass > /dev/null
$S study $ROOT/examples/studies/flexure.toml --out-dir flexure > /dev/null
$S study $ROOT/examples/studies/motor_constant.toml --out-dir motor_constant > /dev/null
# The measure-and-compensate page's first measurement, from the page's own files.
python3 - "$ROOT/docs/src/tutorials/measure-and-compensate.md" <<'PY'
import re, sys
page = open(sys.argv[1]).read()
for name, text in re.findall(r'<!-- file: (\S+) -->\n```toml\n(.*?)```', page, re.S):
    open(name, "w").write(text)
exec(re.search(r'```sh\npython3 -c "\n(import math.*?)"\n```', page, re.S).group(1))
PY
$S frf -c lab.toml --loop open --points 40 --from 20 --to 10000 --out-dir lab > /dev/null
$S identify lab/frf.csv -o lab/model.toml > /dev/null
$S measure -c cut.toml --plant lab/model.toml --feedforward zpetc --out part-0.xyz --seed 1 > /dev/null
$S register -c cut.toml part-0.xyz --setting-errors --out-dir register-0 > /dev/null
mkdir -p $ROOT/docs/src/gallery
python3 - "$W" "$ROOT/docs/src/gallery" <<'PY'
import sys
from PIL import Image
src, dst = sys.argv[1], sys.argv[2]
for f, name in [("frf/bode.png","bode.png"),("budget/budget_psd.png","budget_psd.png"),("budget/budget_cas.png","budget_cas.png"),("budget/sweep.png","sweep.png"),("stiffness/compliance.png","compliance.png"),("machine/form_error_map.png","form_error_map.png"),("machine/trajectory.png","trajectory.png"),("repetitive/repetitive_convergence.png","repetitive_convergence.png"),("repetitive/repetitive_table.png","repetitive_table.png"),("repetitive/form_error_map.png","repetitive_form_error_map.png"),("toolpath/fts_path.png","toolpath_fts_path.png"),("toolpath/predicted_form_error.png","toolpath_predicted_form_error.png"),("toolpath/bands.png","toolpath_bands.png"),("moving_mass/study.png","study_mass.png"),("flexure/map-h2.png","study_flexure.png"),("motor_constant/sensitivity.png","study_motor_sensitivity.png"),("register-0/measured_residual.png","measured_residual.png"),("register-0/part_residual.png","part_residual.png")]:
    im = Image.open(f"{src}/{f}").convert("RGB")
    w = 760
    im = im.resize((w, round(im.height * w / im.width)), Image.LANCZOS)
    im = im.quantize(colors=256, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
    im.save(f"{dst}/{name}", optimize=True)
PY
rm -rf $W
ls -la $ROOT/docs/src/gallery
