#!/usr/bin/env bash
# The sweeps docs/fidelity.md reports: every profile with and without street-imagery anchors
# (good receiver), the typical profile with a phone receiver, 200 drives each (held-out seeds
# 1001-1100, careful and careless), the issue's 24 careful drives on the ideal profile,
# 200 one-minute typical drives (the mount calibration's target is after 60 s of driving) and
# 40 ten-minute drives on the ideal and typical profiles; and issue #55's verdicts with their
# doubt: seeds 14301-14425 with every kind of driver (1 000 drives each) with street anchors,
# without, and with a phone receiver.
# Usage: scripts/fidelity_sweeps.sh [DASH2SIM] [OUT]   (about 35 minutes on 2 cores)
set -euo pipefail
D2S="${1:-target/release/dash2sim}"
OUT="${2:-target/fidelity}"
mkdir -p "$OUT"
for profile in ideal typical hard; do
  for anchors in street none; do
    "$D2S" scenario sweep --seeds 1001-1100 --driver both --profile "$profile" --anchors "$anchors" \
      -o "$OUT/$profile-$anchors" -q > "$OUT/$profile-$anchors.txt"
  done
done
for anchors in street none; do
  "$D2S" scenario sweep --seeds 1001-1100 --driver both --profile typical --receiver phone --anchors "$anchors" \
    -o "$OUT/typical-phone-$anchors" -q > "$OUT/typical-phone-$anchors.txt"
done
"$D2S" scenario sweep --seeds 1-24 --driver careful --profile ideal -o "$OUT/ideal-1-24" -q > "$OUT/ideal-1-24.txt"
"$D2S" scenario sweep --seeds 1001-1100 --driver both --profile typical --duration 60 \
  -o "$OUT/typical-60s" -q > "$OUT/typical-60s.txt"
for profile in ideal typical; do
  "$D2S" scenario sweep --seeds 1001-1020 --driver both --profile "$profile" --duration 600 \
    -o "$OUT/long-$profile" -q > "$OUT/long-$profile.txt"
done
for setting in "--anchors street" "--anchors none" "--receiver phone"; do
  name="kinds-$(echo "$setting" | tr -d ' -')"
  # shellcheck disable=SC2086 # the setting is two words on purpose
  "$D2S" scenario sweep --seeds 14301-14425 --driver all $setting -o "$OUT/$name" -q > "$OUT/$name.txt"
done
echo "summaries in $OUT/*.txt and $OUT/*/summary.json"
