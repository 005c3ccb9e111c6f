#!/usr/bin/env bash
# Sixteen large analyses (100,001 points, a 55 MB JSON answer each) posted at once to the web
# port of a geotrajd started here, the server's RSS sampled every 0.1 s, and ten gRPC plans
# with a 1 s deadline made beside them (docs/reliability.md, "Hostile clients").
#   usage: scripts/web_analyses_load.sh [BUILD_DIR]     (default: build; needs curl, bc)
set -u
cd "$(dirname "$0")/.."
b=${1:-build}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 - <<'PY' > "$tmp/analyze_big.json"
import json
r=json.load(open('client/grpcurl/analyze_demo_path_a.json'))
r['analysisPoints']=100001
print(json.dumps(r))
PY
$b/server/geotrajd --address 127.0.0.1:15051 --web-address 127.0.0.1:18080 > "$tmp/geotrajd.log" 2>&1 &
pid=$!
sleep 1.5
( while kill -0 $pid 2>/dev/null; do r=$(ps -o rss= -p $pid); echo $r; sleep 0.1; done ) > "$tmp/rss.txt" &
sampler=$!
start=$(date +%s.%N)
for k in $(seq 16); do curl -s -o /dev/null -w "%{http_code} %{size_download}\n" -X POST --data-binary @"$tmp/analyze_big.json" http://127.0.0.1:18080/v1/analyze > "$tmp/an_$k.txt" & done
ok=0; fail=0
for k in $(seq 10); do
  if $b/client/geotraj --server 127.0.0.1:15051 --timeout 1 plan client/grpcurl/plan_demo_path_c.json > /dev/null 2>"$tmp/planerr.txt"; then ok=$((ok+1)); else fail=$((fail+1)); fi
  sleep 0.2
done
wait $(jobs -p | grep -v "^$sampler$" | grep -v "^$pid$") 2>/dev/null
end=$(date +%s.%N)
sleep 2
after=$(ps -o rss= -p $pid)
kill -TERM $pid; wait $pid 2>/dev/null; kill $sampler 2>/dev/null
echo "analyses: $(cat "$tmp"/an_*.txt | sort | uniq -c | tr '\n' ';')"
echo "plans with 1 s deadline: ok $ok failed $fail ($(head -c 200 "$tmp/planerr.txt"))"
echo "RSS peak $(sort -n "$tmp/rss.txt" | tail -1) kB, 2 s after $after kB; wall $(echo "$end - $start" | bc) s"
