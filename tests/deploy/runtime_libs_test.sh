#!/usr/bin/env bash
# The container image's pieces, checked without a container engine:
#  1. every shared library the binaries need (DT_NEEDED, transitively, at the paths `ldd`
#     reports) is provided by a package in deploy/runtime-packages.txt (dpkg -S on the
#     library, its /usr path, the resolved file; for a library chosen by update-alternatives,
#     such as libblas.so.3, any installed package shipping a file of that name counts);
#  2. every listed package is installed here and provides at least one of those libraries
#     (no stale entries);
#  3. the Dockerfile's build stage runs scripts/install-deps.sh and scripts/build.sh, and
#     every scripts/... or deploy/... file the Dockerfile names exists.
#   usage: runtime_libs_test.sh SOURCE_DIR BINARY...
set -euo pipefail
src="$1"; shift
packages_file="$src/deploy/runtime-packages.txt"
dockerfile="$src/deploy/Dockerfile"
failures=0
fail() { echo "FAIL: $*" >&2; failures=$((failures + 1)); }

if ! command -v ldd > /dev/null || ! command -v dpkg > /dev/null; then echo "SKIP: no ldd or dpkg"; exit 77; fi

mapfile -t listed < <(sed -e 's/#.*//' -e 's/[[:space:]]//g' "$packages_file" | grep -v '^$')
declare -A is_listed used
for p in "${listed[@]}"; do is_listed[$p]=1; done

# The libraries the binaries need: their DT_NEEDED entries, and those of every library
# needed in turn, resolved to the paths `ldd` reports. A library that update-alternatives
# chooses (a symlink chain through /etc/alternatives, as libblas.so.3) is needed by its
# file name only: any provider will do, and what the chosen one needs in turn (ATLAS's
# libatlas.so.3) is not followed.
declare -A path_of alternative
libs=()
for bin in "$@"; do
  [ -x "$bin" ] || { fail "$bin is not an executable"; continue; }
  out="$(ldd "$bin")"
  if grep -q 'not found' <<< "$out"; then
    fail "$bin: libraries not found here: $(grep 'not found' <<< "$out" | tr -s ' \t' ' ')"
  fi
  while read -r soname path; do path_of[$soname]="$path"; done < <(
    awk '$2 == "=>" && $3 ~ /^\// { print $1, $3 }' <<< "$out")
  # The loader: "/lib64/ld-linux-x86-64.so.2 (0x...)".
  while read -r loader; do libs+=("$loader"); path_of[$(basename "$loader")]="$loader"; done < <(
    awk '$1 ~ /^\// { print $1 }' <<< "$out")
done
needed() { readelf -d "$1" 2>/dev/null | sed -n 's/.*(NEEDED).*\[\(.*\)\]/\1/p'; }
is_alternative() {
  local link="$1" target
  while [ -L "$link" ]; do
    target="$(readlink "$link")"
    case "$target" in /etc/alternatives/*) return 0 ;; esac
    case "$target" in /*) link="$target" ;; *) link="$(dirname "$link")/$target" ;; esac
  done
  return 1
}
declare -A seen
queue=()
for bin in "$@"; do [ -x "$bin" ] && while read -r so; do queue+=("$so"); done < <(needed "$bin"); done
while [ ${#queue[@]} -gt 0 ]; do
  so="${queue[0]}"; queue=("${queue[@]:1}")
  [ -n "${seen[$so]:-}" ] && continue
  seen[$so]=1
  path="${path_of[$so]:-}"
  [ -n "$path" ] || { fail "$so: needed but not reported by ldd"; continue; }
  libs+=("$path")
  if is_alternative "$path"; then alternative[$path]=1; continue; fi
  while read -r next; do queue+=("$next"); done < <(needed "$(readlink -f "$path")")
done
mapfile -t libs < <(printf '%s\n' "${libs[@]}" | sort -u)
[ ${#libs[@]} -gt 1 ] || fail "ldd and readelf reported no libraries"

# Owners of many paths in one dpkg -S call (it is slow per call): "path<TAB>package" lines.
owner_lines() {
  dpkg -S "$@" 2>/dev/null | awk -F': ' '{ n = split($1, p, ", "); for (i = 1; i <= n; i++) { sub(/:.*/, "", p[i]); print $2 "\t" p[i] } }' || true
}
queries=()
for lib in "${libs[@]}"; do
  queries+=("$lib" "$(readlink -f "$lib")")
  case "$lib" in /lib/* | /lib64/*) queries+=("/usr$lib") ;; esac
  if [ -n "${alternative[$lib]:-}" ]; then queries+=("*/$(basename "$lib")"); fi
done
owner_table="$(owner_lines "${queries[@]}")"

for lib in "${libs[@]}"; do
  real="$(readlink -f "$lib")"
  if [ -n "${alternative[$lib]:-}" ]; then
    name="$(basename "$lib")"
    mapfile -t provs < <(awk -F'\t' -v n="$name" '{ k = split($1, a, "/"); if (a[k] == n) print $2 }' <<< "$owner_table" | sort -u)
  else
    mapfile -t provs < <(awk -F'\t' -v a="$lib" -v b="/usr$lib" -v c="$real" '$1 == a || $1 == b || $1 == c { print $2 }' <<< "$owner_table" | sort -u)
  fi
  found=""
  for p in "${provs[@]}"; do
    [ -n "$p" ] || continue
    if [ -n "${is_listed[$p]:-}" ]; then found="$p"; used[$p]=1; fi
  done
  if [ -z "$found" ]; then
    fail "$lib: provided by '${provs[*]:-no installed package}', none of which is in deploy/runtime-packages.txt"
  fi
done

for p in "${listed[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed'; then
    fail "deploy/runtime-packages.txt: $p is not installed here (is the name right?)"
  elif [ -z "${used[$p]:-}" ]; then
    fail "deploy/runtime-packages.txt: $p provides none of the libraries the binaries load; remove it"
  fi
done

# The Dockerfile: its build stage runs the scripts CI runs, and the files it names exist.
build_stage="$(awk '/^FROM .* AS build$/ { on = 1; next } /^FROM / { on = 0 } on' "$dockerfile")"
for script in scripts/install-deps.sh scripts/build.sh; do
  grep -Eq "^RUN .*bash $script|^ +.*bash $script|&& bash $script" <<< "$build_stage" \
    || fail "deploy/Dockerfile: the build stage does not run $script"
done
while read -r path; do
  [ -e "$src/$path" ] || fail "deploy/Dockerfile names $path, which does not exist"
done < <(grep -v '^ *#' "$dockerfile" | grep -oE '(scripts|deploy)/[A-Za-z0-9_./-]+' | sort -u)

echo "checked ${#libs[@]} libraries of $# binaries against ${#listed[@]} packages"
if [ "$failures" -gt 0 ]; then
  echo "$failures failure(s)" >&2
  exit 1
fi
echo "runtime_libs_test: OK"
