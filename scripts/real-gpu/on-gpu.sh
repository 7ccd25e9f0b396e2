#!/usr/bin/env bash
# Run from the project root on the machine with the GPU, after prepare.sh (its .gpu/ folder carried along).
# Writes to ${OUT:-/tmp/gpu-out}: log.txt (adapter, self-tests, test failures), gputest.log (GL),
# gputest-vulkan.log, selftest-gl.json, selftest-vulkan.json with the frames each compared (selftest-*/),
# validation-layer.log (the Khronos validation layer's reports over the Vulkan runs: empty when clean), and
# a few frames. GPUTEST_THREADS (default 4, as the first NVIDIA run) and GPUTEST_S (default 300, per pass)
# bound the test runs.
set -u
R=$PWD; O=${OUT:-/tmp/gpu-out}; mkdir -p "$O"; L=$O/log.txt
# The loaders, only where the machine lacks them (the driver itself comes with the machine).
if ! ldconfig -p | grep -q "libEGL.so.1"; then for f in .gpu/gl/*.deb; do dpkg -x "$f" /; done; ldconfig; fi
export CLIPSAT_DATA=$R/.gpu/data CLIPSAT_CACHE=/tmp/clipsat-cache
B=$R/.gpu/clipsat-test
# The test binary looks for tests/goldens under the build machine's project root.
root=$(cat .gpu/build_root); [ "$root" = "$R" ] || { mkdir -p "$(dirname "$root")"; ln -sfn "$R" "$root"; }
nvidia-smi -L >>"$L" 2>&1
if ! $B render --json --out "$O/default.png" >"$O/default.json" 2>>"$L"; then
  export __EGL_VENDOR_LIBRARY_FILENAMES=/usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json
  export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json
  $B render --json --out "$O/default.png" >"$O/default.json" 2>>"$L" || echo "render failed" >>"$L"
fi
grep -o '"gl_version": "[^"]*"' "$O/default.json" >>"$L"
# The self-test, first: check by check, on GL (the strict context) and on Vulkan.
# Every Vulkan device below runs under the Khronos validation layer (.gpu/vulkan-layer, as in CI).
export VK_LAYER_PATH=$R/.gpu/vulkan-layer CLIPSAT_VALIDATION_LOG=$O/validation-layer.log
for g in strict vulkan; do
  $B selftest --gpu $g >>"$L" 2>&1; echo "selftest $g rc $?" >>"$L"
  $B selftest --gpu $g --json --images "$O/selftest-$g" >"$O/selftest-$g.json" 2>>"$L"
done
# The CLI tests inside the GPU binary run the test build's clipsat from the build's target folder.
mkdir -p "$root/target/debug" "$root/target/tmp" && cp .gpu/clipsat-test "$root/target/debug/clipsat"
threads=${GPUTEST_THREADS:-4}
(cd "$root" && timeout ${GPUTEST_S:-300} "$R/.gpu/gputest" --test-threads "$threads" >"$O/gputest.log" 2>&1; echo "gputest (GL) rc $?" >>"$L")
grep -E "FAILED|test result|panicked at" "$O/gputest.log" >>"$L"
(cd "$root" && CLIPSAT_GPU=vulkan WGPU_VALIDATION=1 WGPU_DEBUG=1 timeout ${GPUTEST_S:-300} "$R/.gpu/gputest" --test-threads "$threads" >"$O/gputest-vulkan.log" 2>&1; echo "gputest (Vulkan) rc $?" >>"$L")
grep -E "FAILED|test result|panicked at" "$O/gputest-vulkan.log" >>"$L"
for g in gl vulkan; do
  v=""; [ $g = vulkan ] && v=vulkan
  (cd "$root" && CLIPSAT_GPU=$v WGPU_VALIDATION=${v:+1} WGPU_DEBUG=${v:+1} timeout 120 "$R/.gpu/owndevicetest" >"$O/owndevice-$g.log" 2>&1; echo "own_device ($g) rc $?" >>"$L")
done
T=$R/.gpu/data/ps_height_1k.png
for scene in evening noon; do
  $B render --terrain "$T" --spacing 160 --profile desktop --shading sg --scene $scene --size 1280x720 --out "$O/sg-$scene.png" --json >/dev/null 2>>"$L"
done
$B render --terrain "$T" --spacing 160 --profile desktop --debug levels --size 1280x720 --out "$O/levels.png" --json >/dev/null 2>>"$L"
$B render --terrain "$T" --spacing 160 --profile desktop --size 1280x720 --out "$O/basic.png" --json >/dev/null 2>>"$L"
echo "validation layer: $(grep -c '' "$CLIPSAT_VALIDATION_LOG" 2>/dev/null || echo 0) report lines" >>"$L"
cat "$L"
