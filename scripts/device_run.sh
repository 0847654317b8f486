#!/usr/bin/env bash
# The GPU measurements of reports/performance.md (issue 15), run on a lent GPU machine from the repository root:
#
#   bash scripts/device_run.sh [bench] [studies] [sweep] [dask] [single] [profile] [fig4x3] [hier] [fig4paper]
#                              [side] [fig4prof] [reproduce] [pixels] [marches] [determinism]
#                              [wallprof]
#                                                                                   (default: bench studies)
#
#   bench   : `study bench --backends cuda` — methods, exact queries (ray_intersect, _preliminary, ray_test) and
#             the measured floors (texture fetch rates, copy bandwidth) → perf/
#   studies : fig4, fig5, fig6 and the main sweep with --backend cuda (renders cuda_ad_rgb, exact hits OptiX),
#             cold (fresh cache, fresh Dr.Jit kernel cache), each timed → studies/
#   dask    : configs/sweep_dask.toml (2000 cases) on a Dask cluster of $DASK_PER_GPU (4) workers per GPU
#             (--dask local-gpus), on 1, 2, … GPUs ($DASK_GPUS, default: 1 and every visible GPU): fixed cost and
#             steady cases/s of each run → dask/, dask-<k>gpu.json, times.csv; tables compared → dask-tables.txt
#   sweep   : the main sweep alone, every case profiled in its worker (STUDY_PROFILE) → profiles.tgz
#   single  : the 104-case subset of sweep_large in one process, no Dask (the reference table for the Dask runs)
#   profile : scripts/profile_case.py on the main sweep's heaviest case and on fig4 (cProfile, cold and warm)
#   fig4x3  : fig4 cold, with a warm kernel cache, and with every cache warm (what compiling kernels costs)
#   hier    : scripts/hier_bench.py --backend cuda: linear_secant(1) and layered(1), hierarchical search against the
#             texel march, and localized(10), on the close-up batch: ms, × floor, lookups per ray → perf/hier-cuda.*
#   fig4paper: fig4, fig5, fig6 at paper quality (--quality paper: 1024² camera) with --backend cuda, so FLIP runs
#             on the GPU (study/measure/flip.py): each cold (fresh study caches, fresh kernel cache; fig4's target
#             ≤ 20 s; fig4 under cProfile → profile-fig4paper.txt), then fig4 with the kernel cache warm
#             → results-paper.tgz (reports/paper/fig4, fig5, fig6 without EXRs and viewer)
#
# Wheels: the machine has Python 3.12 without mitsuba/drjit/embreex/pydantic/dask; cp312 wheels are installed
# from $WHEELS/a and $WHEELS/b (default .devcarry; how to make them: ../shared/field-notes.md, "Device (GPU) runs"),
# or unpacked from $WHEELS/site.tar.xz (the same wheels unzipped into one folder and tarred with xz: 33 MB, so that
# they travel beside the repository within the 64 MiB limit).
# Everything is written under $OUT (default ./out-device): one log per part and one results-<part>.tgz each.
#
# Provenance (issue 55): the copy that travels has no .git, so before it travels run, where .git is,
#   bash scripts/device_run.sh stamp
# which writes .study-stamp.json (commit, dirty, diff hash: study.harness.provenance.write_stamp; git-ignored, so
# pass it to the lent machine as carried: run(..., carry=[".study-stamp.json"])). Every table made there names
# that commit in its metadata.json; without the stamp its git_commit is "unknown" (and this script says so).
set -uo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = stamp ]; then   # here, not on the lent machine: the stamp the copy carries
  PYTHONPATH=$PWD ${STUDY_PYTHON:-$( [ -x .venv/bin/python ] && echo .venv/bin/python || echo python3 )} -c \
    "import json; from study.harness.provenance import write_stamp; print(json.dumps(write_stamp()))" || exit 3
  exit 0
fi
if [ ! -d .git ] && [ ! -f .git ] && [ ! -f .study-stamp.json ]; then
  echo "device_run: no .git and no .study-stamp.json: tables will say git_commit \"unknown\"" \
       "(run 'bash scripts/device_run.sh stamp' before the copy travels, and carry the file)" >&2
fi
OUT=${OUT:-$PWD/out-device}; mkdir -p "$OUT"
WHEELS=${WHEELS:-.devcarry}
export PYTHONUNBUFFERED=1 NCCL_NVLS_ENABLE=0
if ! python3 -c "import mitsuba, drjit, embreex, pydantic" 2>/dev/null; then
  if [ -f "$WHEELS/site.tar.xz" ]; then     # the wheels unpacked and xz-compressed: 30 MB instead of 53 MB
    mkdir -p /tmp/site && tar xJf "$WHEELS/site.tar.xz" -C /tmp/site || exit 3
  else
    python3 -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
      "$WHEELS"/a/*.whl "$WHEELS"/b/*.whl || exit 3
  fi
  export PYTHONPATH=/tmp/site:$PWD
fi
export PYTHONPATH=${PYTHONPATH:-}:$PWD
# bytecode made once, as pip makes it at install time: otherwise the first command of a call compiles the wheels'
# and study's modules on import (about 2 s) and the commands after it do not
python3 -m compileall -q -j 0 /tmp/site study ${OLD:+"$OLD/study"} > /dev/null 2>&1 || true
S="python3 -m study.cli"
parts=${*:-bench studies}
nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv > "$OUT/gpu.txt" 2>&1
W=/tmp/study-work; rm -rf "$W"; mkdir -p "$W"

timed() {   # timed NAME command...: wall seconds of the command appended to $OUT/times.csv
  local name=$1; shift
  local t0; t0=$(date +%s.%N)
  "$@"; local rc=$?
  echo "$name,$(python3 -c "import time; print(f'{time.time() - $t0:.1f}')"),$rc" | tee -a "$OUT/times.csv"
  return 0
}

for part in $parts; do
  case $part in
  bench)
    timed bench $S bench --out "$W/perf" --tag gpu --backends cuda --repeats 5 2>&1 | tee "$OUT/log-bench.txt"
    tar czf "$OUT/results-bench.tgz" -C "$W" perf ;;
  studies)
    export HOME=$W/home; mkdir -p "$HOME"                                     # a fresh Dr.Jit kernel cache
    for f in fig4 fig5 fig6; do
      timed "$f" $S figure $f --backend cuda --cache "$W/cache" --out "$W/studies/$f" 2>&1 | tail -40
    done
    tar czf "$OUT/results-figures.tgz" -C "$W" --exclude=exr --exclude=viewer --exclude="*.png" studies
    timed sweep timeout "${SWEEP_LIMIT:-300}" $S sweep configs/sweep.toml --backend cuda --cache "$W/cache" \
      --out "$W/sweep" --jobs "${SWEEP_JOBS:-8}" --no-plots 2>&1 | tail -5
    tar czf "$OUT/results-sweep.tgz" -C "$W" --exclude=cases sweep ;;
  dask)   # configs/$DASK_CONFIG.toml (default sweep_dask: 2000 cases) on a Dask cluster of $DASK_PER_GPU (4) workers
          # per GPU on 1, 2, … GPUs ($DASK_GPUS, default "1 N": one and every visible GPU; DASK_GPUS="1" on a one-GPU
          # machine), each with a cold study cache. Each run prints (and logs to $OUT/log-dask-<k>gpu.txt) its fixed
          # cost (cluster start, warm-up, shutdown) and its steady cases/s, also in dask/gpus<k>/metadata.json
          # ("dask") and $OUT/dask-<k>gpu.json; every table after the first is compared with the first (timings
          # aside) → $OUT/dask-tables.txt. DASK_WARM=1: Dr.Jit's kernel cache filled first by an untimed run of 104
          # cases and shared (as on a user's machine after the first sweep), else a fresh one for each run.
    per=${DASK_PER_GPU:-4}; n=$(nvidia-smi -L | grep -c "^GPU ")
    cfg=configs/${DASK_CONFIG:-sweep_dask}.toml
    sed 's/steps = 256/steps = 52/' configs/sweep_large.toml > configs/sweep_large_subset.toml
    if [ -n "${DASK_WARM:-}" ]; then    # compile the kernels once (Dr.Jit's kernel cache, shared by the runs below,
      export HOME=$W/home-dask; mkdir -p "$HOME"   # as on a user's machine after the first sweep); not timed
      CUDA_VISIBLE_DEVICES=0 $S sweep configs/sweep_large_subset.toml --backend cuda --cache "$W/dcache-warm" \
        --out "$W/dask-warm" --dask local-gpus --jobs "$per" --no-plots > /dev/null 2>&1
    fi
    first=
    for k in ${DASK_GPUS:-1 $n}; do
      [ -z "${DASK_WARM:-}" ] && export HOME=$W/home-$k && mkdir -p "$HOME"
      CUDA_VISIBLE_DEVICES=$(seq -s, 0 $((k - 1))) timed "dask-${k}gpu" timeout "${LIMIT_DASK:-500}" $S sweep "$cfg" \
        --backend cuda --cache "$W/dcache-$k" --out "$W/dask/gpus$k" --dask local-gpus --jobs "$per" --no-plots 2>&1 \
        | tee "$OUT/log-dask-${k}gpu.txt" | tail -2
      echo "dask-${k}gpu-cases,$(ls "$W/dask/gpus$k/cases" 2>/dev/null | wc -l)" | tee -a "$OUT/times.csv"
      python3 -c "import json, sys; t = json.load(open(sys.argv[1]))['dask']; print(json.dumps(t, indent=1))
print(f\"dask-{sys.argv[2]}gpu-fixed_s,{t['fixed_s']}\ndask-{sys.argv[2]}gpu-steady_cases_per_s,{t['steady_cases_per_s']}\")" \
        "$W/dask/gpus$k/metadata.json" "$k" > "$OUT/dask-${k}gpu.json" 2>&1 && tail -2 "$OUT/dask-${k}gpu.json" \
        | tee -a "$OUT/times.csv"
      if [ -z "$first" ]; then first=$k; else   # the same table on k GPUs as on the first run's, timings aside
        python3 -c "import sys; from study.tables import read_csv
a, b = (read_csv(f'{d}/results.csv') for d in sys.argv[1:])
bad = [(ra['case'], k) for ra, rb in zip(a, b) for k in ra if 'seconds' not in k and ra[k] != rb.get(k)
       and not (ra[k] != ra[k] and rb.get(k) != rb.get(k))]
print(f'{sys.argv[2]} vs {sys.argv[1]}: {len(a)} / {len(b)} rows,', 'identical' if len(a) == len(b) and not bad
      else f'DIFFERENT ({len(bad)} cells, first {bad[:3]})')" "$W/dask/gpus$first" "$W/dask/gpus$k" \
          | tee -a "$OUT/dask-tables.txt"
      fi
    done
    tar czf "$OUT/results-dask.tgz" -C "$W" --exclude=cases dask ;;
  single)  # the 104-case subset in one process on GPU 0, no Dask: the reference table for the Dask runs
    sed 's/steps = 256/steps = 52/' configs/sweep_large.toml > configs/sweep_large_subset.toml
    export HOME=$W/home-single; mkdir -p "$HOME"
    CUDA_VISIBLE_DEVICES=0 timed single timeout "${LIMIT_S:-200}" $S sweep configs/sweep_large_subset.toml \
      --backend cuda --cache "$W/scache" --out "$W/single" --no-plots 2>&1 | tail -2
    tar czf "$OUT/results-single.tgz" -C "$W" --exclude=cases single ;;
  profile)  # where the main sweep's last case (its finest cube, big columns) and fig4 spend their time on the GPU:
            # each run twice under cProfile in one process (scripts/profile_case.py), on an empty cache, then warm
    export HOME=$W/home-prof; mkdir -p "$HOME"
    timed profile python3 scripts/profile_case.py configs/sweep.toml cuda "${PROFILE_CASE:--1}" "$W/pcache" \
      > "$OUT/profile-case.txt" 2>&1
    timed profile-fig4 python3 scripts/profile_case.py configs/fig4.toml cuda fig4 "$W/pcache4" \
      > "$OUT/profile-fig4.txt" 2>&1 ;;
  sweep)    # the main sweep alone, cold, each case profiled in its worker (STUDY_PROFILE) → profiles.tgz
    export HOME=$W/home-sweep; mkdir -p "$HOME"
    STUDY_PROFILE=$W/profs timed sweep-only timeout "${SWEEP_LIMIT:-300}" $S sweep configs/sweep.toml --backend cuda \
      --cache "$W/scache" --out "$W/sweep-only" --jobs "${SWEEP_JOBS:-8}" --no-plots 2>&1 | tail -2
    tar czf "$OUT/profiles.tgz" -C "$W" profs
    tar czf "$OUT/results-sweep-only.tgz" -C "$W" --exclude=cases sweep-only ;;
  fig4x3)   # fig4 three times: cold; fresh study cache but Dr.Jit's kernel cache warm (the difference: compiling
            # kernels); study cache warm too (what is left: metrics, figure, viewer, imports)
    export HOME=$W/home-x3; mkdir -p "$HOME"
    timed fig4-cold $S figure fig4 --backend cuda --cache "$W/c1" --out "$W/x3a" > /dev/null 2>&1
    timed fig4-kernels-warm $S figure fig4 --backend cuda --cache "$W/c2" --out "$W/x3b" > /dev/null 2>&1
    timed fig4-all-warm $S figure fig4 --backend cuda --cache "$W/c2" --out "$W/x3c" > /dev/null 2>&1 ;;
  hier)     # the hierarchical search against the texel march on the close-up batch (1024², cube 256²): ms, × floor,
            # lookups per ray, × localized(10) for linear_secant(1) and layered(1), both ways → perf/hier-cuda.*
    timed hier python3 scripts/hier_bench.py --backend cuda --scene-res 1024 --repeats 5 --out "$W/perf" 2>&1 \
      | tee "$OUT/log-hier.txt"
    tar czf "$OUT/results-hier.tgz" -C "$W" perf ;;
  fig4paper)  # fig4 profiled, then fig5 and fig6, at paper quality, each cold (fresh study cache; one fresh kernel cache)
    export HOME=$W/home-paper; mkdir -p "$HOME"                               # a fresh Dr.Jit kernel cache
    timed fig4-paper-cold python3 -m cProfile -o "$OUT/fig4paper-cold.prof" -m study.cli figure fig4 --quality paper \
      --backend cuda --cache "$W/pc1" --out "$W/paper/fig4" 2>&1 | tail -30          # profiled: where the time goes
    python3 -c "import pstats,sys; pstats.Stats(sys.argv[1]).sort_stats('cumulative').print_stats(60)" \
      "$OUT/fig4paper-cold.prof" > "$OUT/profile-fig4paper.txt" 2>&1
    for f in fig5 fig6; do
      timed "$f-paper-cold" $S figure $f --quality paper --backend cuda --cache "$W/pc-$f" --out "$W/paper/$f" \
        2>&1 | tail -3
    done
    timed fig4-paper-kernels-warm $S figure fig4 --quality paper --backend cuda --cache "$W/pc2" \
      --out "$W/paper-warm/fig4" > /dev/null 2>&1
    tar czf "$OUT/results-paper.tgz" -C "$W" --exclude=exr --exclude=viewer paper ;;
  fig4prof)  # this commit's fig4 at paper quality, cold under cProfile (per-stage split: the callees of run_case,
             # sorted by cumulative time → profile-fig4prof.txt), then with the kernel cache warm
    export HOME=$W/home-fp; mkdir -p "$HOME"
    timed fig4prof-paper-cold python3 -m cProfile -o "$OUT/fp.prof" -m study.cli figure fig4 --quality paper \
      --backend cuda --cache "$W/fp1" --out "$W/fp/fig4" > "$OUT/log-fig4prof.txt" 2>&1
    python3 -c "import pstats,sys; s = pstats.Stats(sys.argv[1]); s.sort_stats('cumulative').print_stats(90)
s.print_callees('run_case')" "$OUT/fp.prof" > "$OUT/profile-fig4prof.txt" 2>&1; rm -f "$OUT/fp.prof"
    timed fig4prof-paper-kernels-warm $S figure fig4 --quality paper --backend cuda --cache "$W/fp2" \
      --out "$W/fp/fig4-warm" > /dev/null 2>&1 ;;
  wallprof)  # where the wall clock goes on every thread (scripts/wall_profile.py samples each thread's stack; cProfile
             # sees the case's thread only): the same-work config at paper quality cold, then with the kernels warm,
             # then fig4 at paper quality cold → wallprof-*.txt, each run's time split → log-wallprof-*.txt;
             # WALLPROF_RUNS may also name fig4-256-cold (fig4 at 256², its own cold kernel cache)
    export HOME=$W/home-wp; mkdir -p "$HOME"
    for run in ${WALLPROF_RUNS:-samework-cold samework-warm fig4-cold}; do   # WALLPROF_RUNS: which of them
      q="--quality paper"
      case $run in samework-*) cfg="--config configs/bench/fig4_samework.toml" ;;
        fig4-256-*) cfg=fig4; q=""; export HOME=$W/home-wp256; mkdir -p "$HOME" ;;  # 256², its own cold kernels
        *) cfg=fig4; export HOME=$W/home-wp4; mkdir -p "$HOME" ;; esac   # fig4 with its own, cold kernel cache
      timed "wallprof-$run" python3 scripts/wall_profile.py "$OUT/wallprof-$run.txt" --interval 0.01 \
        -m study.cli figure $cfg \
        $q --backend cuda --cache "$W/wp-$run" --out "$W/wp/$run" > "$OUT/log-wallprof-$run.txt" 2>&1
    done ;;
  side)    # issue-52 targets, the commit before ($OLD, default .devold: `git archive <rev> study configs scenes
           # pyproject.toml | tar x -C .devold`, plus configs/bench/) and this one side by side on one host, each cold
           # (fresh study and kernel caches): the same-work config (configs/bench/fig4_samework.toml) at paper quality
           # cold and with the kernels warm, fig4 at paper quality cold (this commit's under cProfile →
           # profile-side-new.txt, its time split → split-side-*.txt), then the 256² fig4 + fig5 + fig6 + main sweep.
           # $SIDE (default "old new"): which of the two; SIDE_PAPER=0 / SIDE_256=0 skip the paper-quality or the 256²
           # part, SIDE_SAMEWORK=0 / SIDE_FIG4PAPER=0 one of the paper-quality part's two (so that the 10-minute call
           # limit can split them).
    OLD=${OLD:-.devold}
    for which in ${SIDE:-old new}; do
      src=$PWD; [ "$which" = old ] && src=$(cd "$OLD" && pwd)
      export HOME=$W/home-$which; mkdir -p "$HOME"
      # the old tree's git_commit: "unknown", not this checkout's HEAD (its runner asks git from inside $OLD, and
      # git would walk up to this repository)
      ( cd "$src" && export PYTHONPATH=/tmp/site:$src; [ "$which" = old ] && export GIT_CEILING_DIRECTORIES=$src
        if [ "${SIDE_PAPER:-1}" = 1 ]; then
        if [ "${SIDE_SAMEWORK:-1}" = 1 ]; then
        timed "$which-samework-paper-cold" $S figure --config configs/bench/fig4_samework.toml --quality paper \
          --backend cuda --cache "$W/$which-s1" --out "$W/$which/samework" > "$OUT/log-side-$which-samework.txt" 2>&1
        [ "${SIDE_WARM:-1}" = 1 ] && timed "$which-samework-paper-kernels-warm" $S figure \
          --config configs/bench/fig4_samework.toml --quality paper --backend cuda --cache "$W/$which-s2" \
          --out "$W/$which/samework-warm" > /dev/null 2>&1   # SIDE_WARM=0: not this one
        fi
        export HOME=$W/home-$which-f4; mkdir -p "$HOME"
        if [ "${SIDE_FIG4PAPER:-1}" = 0 ]; then :
        elif [ "$which" = new ] && [ "${SIDE_PROFILE:-1}" = 1 ]; then   # SIDE_PROFILE=0: no cProfile
          timed "$which-fig4-paper-cold" python3 -m cProfile -o "$OUT/side-new.prof" -m study.cli figure fig4 \
            --quality paper --backend cuda --cache "$W/$which-p1" --out "$W/$which/paper-fig4" \
            > "$OUT/split-side-$which.txt" 2>&1
          python3 -c "import pstats,sys; s = pstats.Stats(sys.argv[1]); s.sort_stats('cumulative').print_stats(70)
s.print_callees('run_case')" "$OUT/side-new.prof" > "$OUT/profile-side-new.txt" 2>&1; rm -f "$OUT/side-new.prof"
        else
          timed "$which-fig4-paper-cold" $S figure fig4 --quality paper --backend cuda --cache "$W/$which-p1" \
            --out "$W/$which/paper-fig4" > "$OUT/split-side-$which.txt" 2>&1
        fi
        fi
        if [ "${SIDE_256:-1}" = 1 ]; then
        export HOME=$W/home-$which-256; mkdir -p "$HOME"
        for f in fig4 fig5 fig6; do
          timed "$which-$f-256" $S figure $f --backend cuda --cache "$W/$which-c256" --out "$W/$which/$f" > /dev/null 2>&1
        done
        timed "$which-sweep-256" timeout 300 $S sweep configs/sweep.toml --backend cuda --cache "$W/$which-c256" \
          --out "$W/$which/sweep" --jobs 8 --no-plots > /dev/null 2>&1
        fi )
    done
    tar czf "$OUT/results-side.tgz" -C "$W" --exclude=exr --exclude=viewer --exclude="*.png" --exclude=cases \
      $(cd "$W" && ls -d old new 2>/dev/null) ;;
  reproduce)  # scripts/reproduce.sh's commands on this host, on the GPU (reproduce.sh picks cuda where it runs;
              # REPRODUCE_BACKEND=llvm: the committed tables' backend, on the host's cores; REPRODUCE_BACKEND= numpy),
              # $REPRODUCE_JOBS at a time; the reports back as reports-part-*.tar.xz
    export HOME=$W/home-repro; mkdir -p "$HOME"
    STUDY="python3 -m study.cli" STUDY_PYTHON=python3 REPRODUCE_JOBS=${REPRODUCE_JOBS:-8} \
      REPRODUCE_SKIP=${REPRODUCE_SKIP:-animate} REPRODUCE_SKIP_CALIBRATION=1 \
      timeout "${REPRODUCE_LIMIT:-500}" bash scripts/reproduce.sh --no-setup > "$OUT/log-reproduce.txt" 2>&1
    rc=$?; echo "reproduce,rc=$rc" | tee -a "$OUT/times.csv"; tail -30 "$OUT/log-reproduce.txt"
    if [ "$rc" = 0 ] || [ -n "${REPRODUCE_PACK:-}" ]; then   # a run the limit stopped is run again (caches kept)
      tar cf - --exclude=cases --exclude=exr --exclude=animation --exclude=performance --exclude=paper \
        --exclude=baseline --exclude=calibration --exclude=pareto reports | xz -T0 -3 \
        > "$W/reports.tar.xz"
      split -b 15M -d "$W/reports.tar.xz" "$OUT/reports-part-"
    fi ;;
  marches)  # issue 56: the close-up batch kernels of localized(10), linear_secant(1), layered(1), multi_probe,
            # probe_blend and ssr_hiz and their floors (scripts/march_side.py), $OLD (default .devold: `git archive <rev>
            # study configs scenes pyproject.toml | tar x -C .devold`) and this tree side by side on this machine,
            # $MARCH_ROUNDS (2) rounds of old, new interleaved, then this tree with each restructure undone
            # ($MARCH_VARIANTS, default "tables-off look-off"; "" none): kernel ms, × floor, × localized(10), × old,
            # and whether every output (shown, radiance, ratio, valid, lookups) is bit-identical to old's
            # → march-compare.txt; then, if Nsight Compute is here, linear_secant's kernels of both trees (ncu-*.txt).
            # MARCH_RES (1024) rays², MARCH_CUBE (256), MARCH_BACKEND (cuda; llvm to try it on a CPU), MARCH_NCU=0: no
            # ncu, NCU_LIMIT (200) seconds per ncu run, NCU_METHODS (linear_secant) the methods it profiles,
            # NCU_TREES (old new) their trees, NCU_ARGS (--set full --launch-count 20) what ncu collects, MARCH_TREES (old new)
            # the trees timed.
    OLD=${OLD:-.devold}; old=$(cd "$OLD" && pwd) || exit 3
    export HOME=$W/home-march; mkdir -p "$HOME"
    be=${MARCH_BACKEND:-cuda}
    M="--backend $be --scene-res ${MARCH_RES:-1024} --cube-res ${MARCH_CUBE:-256} --repeats ${MARCH_REPEATS:-5}"
    for r in $(seq 1 "${MARCH_ROUNDS:-2}"); do
      for which in ${MARCH_TREES:-old new}; do
        src=$PWD; [ "$which" = old ] && src=$old
        ( cd "$src" && PYTHONPATH=${PYTHONPATH%%:*}:$src timed "march-$which-$r" python3 "$OLDPWD/scripts/march_side.py" \
            --tree "$which" --run "$r" $M --out "$W/march" ) 2>&1 | tee -a "$OUT/log-marches.txt" | tail -2
        cp "$W"/march/*.csv "$OUT/" 2>/dev/null   # each tree's rows come back even if the call runs out of time
      done
    done
    for v in ${MARCH_VARIANTS-tables-off look-off}; do
      timed "march-new-$v" python3 scripts/march_side.py --tree "new-$v" --variant "$v" $M --out "$W/march" 2>&1 \
        | tee -a "$OUT/log-marches.txt" | tail -1
    done
    python3 scripts/march_side.py --compare "$W/march" 2>&1 | tee "$OUT/march-compare.txt"
    tar czf "$OUT/results-marches.tgz" -C "$W" march
    NCU=$(command -v ncu || ls /usr/local/cuda*/bin/ncu /opt/nvidia/nsight-compute/*/ncu 2>/dev/null | head -1)
    { for t in ncu nsys; do echo "$t: $(command -v $t || echo 'not on PATH')"; done; echo "ncu found: ${NCU:-none}"
      nvidia-smi --query-gpu=name,clocks.sm,clocks.max.sm --format=csv; } > "$OUT/tools.txt" 2>&1
    cat "$OUT/tools.txt"
    if [ -n "$NCU" ] && [ "$be" = cuda ] && [ "${MARCH_NCU:-1}" = 1 ]; then   # linear_secant's kernels, per tree
      for which in ${NCU_TREES:-old new}; do
        src=$PWD; [ "$which" = old ] && src=$old
        ( cd "$src" && PYTHONPATH=${PYTHONPATH%%:*}:$src timeout "${NCU_LIMIT:-200}" "$NCU" ${NCU_ARGS:---set full --launch-count 20} \
            -f -o "$W/ncu-$which" python3 "$OLDPWD/scripts/march_side.py" --tree "ncu-$which" --methods "${NCU_METHODS:-linear_secant}" \
            --no-time $M --out "$W/ncu-out" > "$OUT/log-ncu-$which.txt" 2>&1 ) \
          && "$NCU" --import "$W/ncu-$which.ncu-rep" --page details > "$OUT/ncu-$which.txt" 2>&1 \
          || echo "ncu on $which failed (see log-ncu-$which.txt)"
      done
    fi ;;
  determinism)  # issue 52: do two CUDA runs make the same numbers, and at which stage do they part? fig4 at 256²
                # (or $DET_FIGURE) twice cold, each with its own caches, then with the first's render cache copied
                # (warm) at STUDY_THREADS = each of $DET_THREADS ("16 1 8 4"): every wall time, and each run's cache
                # entries and table against the first's (scripts/compare_runs.py) → determinism.txt
    f=${DET_FIGURE:-fig4}; d=$W/det; mkdir -p "$d"
    for i in 1 2; do
      export HOME=$d/home$i; mkdir -p "$HOME"
      timed "det-$f-cold-$i" $S figure "$f" --backend ${DET_BACKEND:-cuda} --cache "$d/c$i" --out "$d/o$i" --images none > "$OUT/log-det-$i.txt" 2>&1
    done
    { echo "## two cold runs, 16 threads: caches, then tables"; python3 scripts/compare_runs.py "$d/c1" "$d/c2"         "$d/o1/metrics.csv" "$d/o2/metrics.csv"; } 2>&1 | tee "$OUT/determinism.txt"
    for t in ${DET_THREADS:-16 1 8 4}; do
      rm -rf "$d/w"; cp -r "$d/c1" "$d/w"; export HOME=$d/home1
      STUDY_THREADS=$t timed "det-$f-warm-threads-$t" $S figure "$f" --backend ${DET_BACKEND:-cuda} --cache "$d/w" --out "$d/t$t" \
        --images none > "$OUT/log-det-t$t.txt" 2>&1
      { echo "## warm copy of run 1's cache, STUDY_THREADS=$t, against run 1"; python3 scripts/compare_runs.py \
          "$d/c1" "$d/w" "$d/o1/metrics.csv" "$d/t$t/metrics.csv"; } 2>&1 | tee -a "$OUT/determinism.txt"
    done ;;
  pixels)   # the image columns on the GPU (study/measure/pixels.py) against scikit-image/numpy, and side by side
    timed pixels python3 scripts/pixels_cuda.py 2>&1 | tee "$OUT/log-pixels.txt" ;;
  *) echo "unknown part $part"; exit 2 ;;
  esac
done
cat "$OUT/times.csv"
