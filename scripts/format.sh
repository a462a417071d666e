#!/usr/bin/env bash
# Formats the C++ sources with the project's .clang-format (Debian's clang-format 14), or with
# --check reports the files that differ from it and fails (CI runs the check).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format > /dev/null || apt-get install -y -qq clang-format > /dev/null
mapfile -t files < <(git ls-files '*.cpp' '*.hpp' '*.h' | grep -v '^tests/fuzz/corpus/')
if [[ "${1:-}" == "--check" ]]; then
  bad=()
  for f in "${files[@]}"; do
    clang-format "$f" | cmp -s - "$f" || bad+=("$f")
  done
  if (( ${#bad[@]} )); then
    printf 'not formatted (run scripts/format.sh): %s\n' "${bad[@]}" >&2
    exit 1
  fi
  echo "format: ${#files[@]} files as .clang-format says"
else
  clang-format -i "${files[@]}"
fi
