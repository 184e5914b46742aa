#!/bin/sh
# A run's report.html, or a study's, in headless Chromium: the page must
# render to its end (a run's script marks <body> data-rendered="ok" and
# window.onerror data-error; a study's plot marks either as it loads) with
# nothing on the console, and a screenshot is kept as the test's artefact,
# report.png or study_report.png.
# Usage: report_in_browser.sh CES_SIM SCENE ARTEFACT_DIR [study]
set -eu
sim=$1 scene=$2 artefacts=$3 kind=${4:-run}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
if [ "$kind" = study ]; then
  "$sim" study "$scene" --vary time.step=2ms,1ms --jobs 2 --threads 1 -o "$tmp/run" > /dev/null
  screenshot=study_report.png
else
  "$sim" "$scene" --set time.end=0.3s --set time.until=end -q -o "$tmp/run"
  screenshot=report.png
fi
browser=$(command -v chromium || command -v chromium-browser || command -v google-chrome) ||
  { echo "no Chromium on the PATH (.ci/setup installs Debian's chromium)"; exit 1; }
open_page() {
  "$browser" --headless --no-sandbox --disable-gpu --user-data-dir="$tmp/profile" \
    --enable-logging=stderr --v=0 --virtual-time-budget=5000 "$@" "file://$tmp/run/report.html"
}
open_page --dump-dom > "$tmp/dom.html" 2> "$tmp/console.log"
if ! grep -q 'data-rendered="ok"' "$tmp/dom.html" || grep -q 'data-error=' "$tmp/dom.html"; then
  echo "report.html did not render:"; grep -o 'data-error="[^"]*"' "$tmp/dom.html" || true
  exit 1
fi
if grep ':CONSOLE(' "$tmp/console.log"; then echo "report.html wrote to the console"; exit 1; fi
mkdir -p "$artefacts"
open_page --window-size=1000,2600 --screenshot="$artefacts/$screenshot" > /dev/null 2>&1
test -s "$artefacts/$screenshot"
echo "rendered; screenshot: $artefacts/$screenshot"
