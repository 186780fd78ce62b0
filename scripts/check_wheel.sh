#!/usr/bin/env bash
# Build seqrank's wheel and check it as a user would install it: in a clean virtual
# environment (torch pinned first, as the README says), away from the source tree:
# --version, --help, a tiny training run, and the labelling page served with its static files.
# `make test` runs this; it needs the project's .venv (for pip) and network or a pip cache.
set -euo pipefail
cd "$(dirname "$0")/.."
source_tree=$(pwd)
work=$(mktemp -d)
server=""
cleanup() {
    if [ -n "$server" ]; then
        kill "$server" 2>/dev/null || true
        wait "$server" 2>/dev/null || true  # it writes its export as it stops
    fi
    rm -rf "$work" 2>/dev/null || { sleep 1; rm -rf "$work"; }
}
trap cleanup EXIT

echo "check_wheel: building"
.venv/bin/python -m pip wheel --quiet --no-deps --wheel-dir "$work/dist" "$source_tree"
wheel=$(ls "$work"/dist/seqrank-*.whl)
for member in seqrank/labelling/static/index.html seqrank/labelling/static/app.js \
    seqrank/labelling/static/app.css seqrank/true_reward_reference.json; do
    .venv/bin/python -c "import sys, zipfile; sys.exit('$member' not in zipfile.ZipFile('$wheel').namelist())" \
        || { echo "check_wheel: $wheel lacks $member"; exit 1; }
done

echo "check_wheel: installing $(basename "$wheel") into a clean virtual environment"
python3 -m venv "$work/venv"
"$work/venv/bin/python" -m pip install --quiet --upgrade pip
"$work/venv/bin/python" -m pip install --quiet torch==2.13.0
"$work/venv/bin/python" -m pip install --quiet "$wheel"

cd "$work"  # nothing from the source tree on the path
version=$(venv/bin/seqrank --version)
expected=$("$source_tree/.venv/bin/python" -c "import tomllib; print(tomllib.load(open('$source_tree/pyproject.toml', 'rb'))['project']['version'])")
[ "$version" = "seqrank $expected" ] || { echo "check_wheel: --version says '$version'"; exit 1; }
venv/bin/seqrank --help >/dev/null
venv/bin/python -c "import seqrank, seqrank.api; assert 'site-packages' in seqrank.__file__"
venv/bin/seqrank train --task dmc:cartpole_swingup --reward true --steps 600 --seed-steps 300 \
    --hidden 32 --batch 32 --eval-every 600 --eval-episodes 1 --device cpu --out run --quiet \
    >/dev/null
[ -f run/summary.json ] || { echo "check_wheel: the tiny run wrote no summary"; exit 1; }

venv/bin/seqrank label offline --task dmc:cartpole_swingup --episodes 1 --questions 2 \
    --port 0 --out labels >"$work/page.log" 2>&1 &
server=$!
url=""
for _ in $(seq 1 120); do
    url=$(grep -o 'http://[^ ]*' "$work/page.log" | head -1 || true)
    [ -n "$url" ] && break
    sleep 1
done
[ -n "$url" ] || { echo "check_wheel: the labelling page did not start"; cat "$work/page.log"; exit 1; }
venv/bin/python - "$url" <<'EOF'
import sys
import urllib.request

url = sys.argv[1]
page = urllib.request.urlopen(url, timeout=30).read().decode()
assert "app.js" in page, "the page does not load its script"
base = url.split("?")[0].rstrip("/")
query = url.split("?", 1)[1] if "?" in url else ""
script = urllib.request.urlopen(f"{base}/static/app.js?{query}", timeout=30).read()
assert len(script) > 1000, "the page's script is missing"
print(f"check_wheel: the labelling page and its static files are served at {base}")
EOF
echo "check_wheel: ok ($(basename "$wheel"))"
