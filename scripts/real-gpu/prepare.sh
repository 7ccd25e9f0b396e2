#!/usr/bin/env bash
# Run from the project root on the build machine. Puts into .gpu/ (git-ignored through .git/info/exclude)
# what a headless run on a machine with a real GPU needs: the GPU test binary, the test build's clipsat
# (the CLI tests run it; on-gpu.sh renders and self-tests with it), the shared terrains and the GL/Vulkan
# loader packages (the GPU machine has the driver but may lack loaders). About 60 MiB with the project's
# files. The test build has the Vulkan backend too (CLIPSAT_GPU=vulkan picks it), and .gpu/vulkan-layer holds
# the Khronos validation layer CI uses (.ci/vulkan-layer), so the Vulkan pass there runs under it too.
# Differs from the first version in where on-gpu.sh comes from (this folder), in building the own_device
# test binary as well, and in finding the exclude file of a worktree; docs/real-drivers.md says how to
# use both.
set -euo pipefail
# A worktree's .git is a file: ask git where the exclude file is.
ex=$(git rev-parse --git-path info/exclude); mkdir -p "$(dirname "$ex")"
grep -qx '/.gpu/' "$ex" 2>/dev/null || echo '/.gpu/' >> "$ex"
rm -rf .gpu && mkdir -p .gpu/gl
exe() {
  cargo test --test "$1" --no-run --message-format=json 2>/dev/null \
    | python3 -c "import json,sys
for l in sys.stdin:
    m=json.loads(l)
    if m.get('reason')=='compiler-artifact' and m.get('executable') and m['target']['name']=='$1': print(m['executable'])" | tail -1
}
cp "$(exe gpu)" .gpu/gputest && cp "$(exe own_device)" .gpu/owndevicetest && cp target/debug/clipsat .gpu/clipsat-test
strip .gpu/gputest .gpu/owndevicetest .gpu/clipsat-test
cp -r ../shared/data .gpu/data
cp scripts/real-gpu/on-gpu.sh .gpu/
# The validation layer beside its manifest (the manifest's path made relative to it); `bash .ci/setup`
# installs it here.
mkdir -p .gpu/vulkan-layer
cp /usr/lib/chromium/libVkLayer_khronos_validation.so .gpu/vulkan-layer/
sed 's#/usr/lib/chromium/#./#' .ci/vulkan-layer/VkLayer_khronos_validation.json \
  > .gpu/vulkan-layer/VkLayer_khronos_validation.json
echo "$PWD" > .gpu/build_root   # the path the test binary has compiled in (CARGO_MANIFEST_DIR)
o='-oAPT::Architecture=amd64 -oAPT::Architectures=amd64 -oDir::State::Lists=/tmp/amd64'
mkdir -p /tmp/amd64/partial && apt-get $o update >/dev/null
(cd .gpu/gl && apt-get $o download libvulkan1 libegl1 libglvnd0 libopengl0 libgl1 libglx0 libgles2 >/dev/null)
du -sh .gpu
