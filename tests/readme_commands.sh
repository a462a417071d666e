#!/bin/sh
# Every qota command in the README's shell blocks, run as written (the qota built here first on
# PATH, data/ the repository's): each must exit 0, and a "$ " command's first line of output must
# be the line the README shows under it. scripts/demo.sh and scripts/test.sh are CI's own.
# Prints "all N commands ran" when so.
#   tests/readme_commands.sh QOTA SOURCE_DIR
set -u
qota=$1 src=$2
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
mkdir "$work/bin"
ln -s "$qota" "$work/bin/qota"
ln -s "$src/data" "$work/data"
cd "$work" || exit 1
# The commands: lines of ```sh blocks that start with "qota " or "$ ", backslash continuations
# joined; a "$ " line is followed by its expected first output line.
awk '/^```sh/{f=1;next} /^```/{f=0} f' "$src/README.md" |
  awk '{ if (c) { line = line " " $0 } else { line = $0 } c = sub(/\\$/, "", line); if (!c) print line }' > lines
n=0 bad=0
expect=""
while IFS= read -r line; do
  if [ -n "$expect" ]; then
    [ "$(head -n 1 out)" = "$line" ] || { echo "FAILED output: $expect"; echo "  got: $(head -n 1 out)"; echo "  README: $line"; bad=$((bad + 1)); }
    expect=""
    continue
  fi
  case $line in
    'qota '[a-z-]*': '*) continue ;;  # (a tool's message shown under its command)
    '$ '*) cmd=${line#'$ '} ;;
    qota\ *) cmd=$line ;;
    *) continue ;;
  esac
  n=$((n + 1))
  if ! PATH="$work/bin:$PATH" sh -c "$cmd" > out 2> err; then
    echo "FAILED: $cmd"; cat err; bad=$((bad + 1))
  fi
  case $line in '$ '*) expect=$cmd ;; esac
done < lines
[ "$bad" -eq 0 ] && echo "all $n commands ran"
