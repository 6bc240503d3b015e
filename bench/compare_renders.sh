#!/usr/bin/env bash
# Render every shipped scene (scenes/**/*.ron) with default outputs using two
# binaries and compare every written file byte for byte.
#
#   bench/compare_renders.sh OLD_BINARY NEW_BINARY [WORK_DIR]
#
# Renders OLD into WORK_DIR/old (skipped when WORK_DIR/old/.done exists, so a
# baseline can be reused) and NEW into WORK_DIR/new, then `cmp`s the trees.
# Exit status 0 only if both trees hold the same files with identical bytes.
set -u
old=$1
new=$2
work=${3:-/tmp/zeroset-compare}
root=$(cd "$(dirname "$0")/.." && pwd)

render_all() {
    local bin=$1 dir=$2
    mkdir -p "$dir"
    local failed=0
    while IFS= read -r scene; do
        local rel=${scene#"$root"/scenes/}
        local out="$dir/${rel%.ron}"
        mkdir -p "$out"
        if ! "$bin" render "$scene" -o "$out" >"$out.log" 2>&1; then
            echo "render failed: $rel ($bin)" >&2
            failed=1
        fi
    done < <(find "$root/scenes" -name '*.ron' | sort)
    return $failed
}

if [ ! -e "$work/old/.done" ]; then
    rm -rf "$work/old"
    render_all "$old" "$work/old" || true
    touch "$work/old/.done"
fi
rm -rf "$work/new"
render_all "$new" "$work/new" || true

status=0
same=0
while IFS= read -r f; do
    rel=${f#"$work"/old/}
    if [ ! -e "$work/new/$rel" ]; then
        echo "missing in new: $rel"
        status=1
    elif cmp -s "$f" "$work/new/$rel"; then
        same=$((same + 1))
    else
        echo "differs: $rel"
        status=1
    fi
done < <(find "$work/old" -type f ! -name '*.log' ! -name '.done' | sort)
while IFS= read -r f; do
    rel=${f#"$work"/new/}
    [ -e "$work/old/$rel" ] || { echo "only in new: $rel"; status=1; }
done < <(find "$work/new" -type f ! -name '*.log' | sort)
echo "identical files: $same"
exit $status
