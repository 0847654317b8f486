#!/usr/bin/env bash
# Build .devcarry/site.tar.xz: the cp312 wheels the GPU machine lacks (its image has numpy, scipy, scikit-image,
# pandas, matplotlib, typer, rich, …; see the device notes), unpacked into one folder and xz-compressed so that
# they travel beside the repository within the 64 MiB limit. scripts/device_run.sh unpacks it there.
# Mitsuba's wheel is pruned to the variants and plugins study uses (field notes, "Device (GPU) runs").
set -euo pipefail
cd "$(dirname "$0")/.."
grep -qx '/.devcarry/' .git/info/exclude 2>/dev/null || grep -q devcarry .gitignore || echo '/.devcarry/' >> .git/info/exclude
d=.devcarry; rm -rf "$d/wheels" "$d/site" && mkdir -p "$d/wheels" "$d/site"
get() {
  python3 -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
    --platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
    --platform manylinux2014_x86_64 --platform manylinux1_x86_64 --platform manylinux_2_34_x86_64 \
    --platform manylinux_2_35_x86_64 -d "$d/wheels" "$@"
}
get mitsuba==3.9.1 drjit==1.5.0 embreex==4.4.0.post1 flip-evaluator==1.7 pydantic==2.14.4 pydantic-core==2.50.5 \
  annotated-types==0.8.0 typing-inspection==0.4.5 typing-extensions==4.16.0 trimesh==5.2.0 tomli-w==1.2.0
if [ -n "${WITH_DASK:-}" ]; then   # only for the Dask runs (device_run.sh dask): 3 MB more
  get dask==2026.8.0 distributed==2026.8.0 partd==1.4.2 locket==1.0.0 tblib==3.2.2 zict==3.0.0 tornado==6.6.1
fi
for w in "$d"/wheels/*.whl; do python3 -m zipfile -e "$w" "$d/site"; done
m="$d/site/mitsuba"
rm -rf "$m"/*mono* "$m"/*spectral* "$m"/*polarized* "$m"/data/srgb.coeff "$m"/data/sunsky "$m"/include "$d/site/share"
find "$m" \( -name 'volpath*' -o -name 'ellipsoids*' -o -name 'bsplinecurve*' -o -name '*sunsky*' \) -exec rm -rf {} +
# plugins and a variant study never asks for (materials, shapes and cameras it does not build; scalar_rgb)
rm -f "$m"/scalar_rgb*.so
for p in principled principledthin hair measured measured_polarized pplastic roughplastic plastic polarizer \
    retarder thinlens irradiancemeter radiancemeter distant cylinder instance shapegroup linearcurve \
    blendbsdf mask bumpmap normalmap; do rm -f "$m/plugins/$p.so"; done
tar cJf "$d/site.tar.xz" -C "$d/site" .
rm -rf "$d/site" "$d/wheels"
ls -la "$d/site.tar.xz"
