#!/bin/bash
# Opens a report.html in headless Chromium (Debian's `chromium` package) and checks that every
# image decodes: exit 0 and "N images, all decoded" when they do, exit 1 naming the problem
# otherwise. With a second argument, also saves a screenshot of the page's top there.
#   scripts/check_report.sh results/report/report.html [shot.png]
set -euo pipefail
html=${1:?usage: scripts/check_report.sh REPORT.html [SCREENSHOT.png]}
shot=${2:-}
[ -f "$html" ] || { echo "check_report: $html: no such file" >&2; exit 1; }
command -v chromium >/dev/null || { echo "check_report: chromium is not installed (apt-get install chromium)" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# A copy with a probe script: after load it writes how many images decoded into the page.
probe='<script>window.addEventListener("load",()=>{const i=[...document.images];const bad=i.filter(x=>!x.complete||x.naturalWidth===0).map(x=>x.alt);document.body.setAttribute("data-check",i.length+" images, "+bad.length+" broken"+(bad.length?": "+bad.join("; "):""));});</script>'
sed "s#</body>#${probe}</body>#" "$html" > "$tmp/report.html"
flags=(--headless --no-sandbox --disable-gpu --allow-file-access-from-files --user-data-dir="$tmp/profile")
dom=$(chromium "${flags[@]}" --virtual-time-budget=10000 --dump-dom "file://$tmp/report.html" 2>"$tmp/log")
result=$(grep -o 'data-check="[^"]*"' <<<"$dom" | head -1 | sed 's/data-check="//; s/"$//' || true)
if [ -n "$shot" ]; then
    chromium "${flags[@]}" --window-size=1200,1600 --screenshot="$shot" "file://$(realpath "$html")" 2>>"$tmp/log"
fi
case "$result" in
    "") echo "check_report: the page did not load in Chromium:" >&2; tail -5 "$tmp/log" >&2; exit 1 ;;
    *", 0 broken") echo "check_report: $html: ${result%, 0 broken}, all decoded"; exit 0 ;;
    *) echo "check_report: $html: $result" >&2; exit 1 ;;
esac
