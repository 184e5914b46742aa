#!/bin/sh
# cmake --install into a fresh prefix: the installed ces-sim names its
# kernel and runs an installed example scene (whose mesh is installed beside
# it), ces-export starts; cpack -G DEB packs the same files and names the
# Debian packages they need. Usage: install.sh BUILD_DIR
set -eu
build=$1
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cmake --install "$build" --prefix "$tmp/usr" > /dev/null
"$tmp/usr/bin/ces-sim" --version | grep "solver kernel: "
"$tmp/usr/bin/ces-sim" "$tmp/usr/share/ces-sim/scenes/hopper.yaml" --set time.end=0.05s -q \
  -o "$tmp/run"
grep -q '"complete": true' "$tmp/run/summary.json"
"$tmp/usr/bin/ces-sim" validate "$tmp/usr/share/ces-sim/scenes/ces_pcb.yaml"
"$tmp/usr/bin/ces-export" --help > /dev/null
test -f "$tmp/usr/share/ces-sim/schema/scene.schema.json"

(cd "$tmp" && cpack -G DEB --config "$build/CPackConfig.cmake" -B "$tmp/pkg" > /dev/null)
deb=$(ls "$tmp"/pkg/ces-sim_*.deb)
dpkg-deb -c "$deb" > "$tmp/contents"
for f in ./usr/bin/ces-sim ./usr/bin/ces-export ./usr/share/ces-sim/schema/scene.schema.json \
         ./usr/share/ces-sim/scenes/ces_pcb.yaml ./usr/share/ces-sim/meshes/chute.stl; do
  grep -q " $f\$" "$tmp/contents" || { echo "$deb lacks $f"; exit 1; }
done
dpkg-deb -f "$deb" Depends | tee /dev/stderr | grep -q libyaml-cpp
echo "installed and packed: $(basename "$deb")"
