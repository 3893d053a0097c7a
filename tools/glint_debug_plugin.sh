#!/usr/bin/env bash
# A copy of a build's libglimmer_closures.so whose glint.cpp object is rebuilt
# with -g added to the Release flags (-O3 unchanged, so the same instructions),
# for line profiles of glint eval: callgrind --dump-instr=yes, callgrind_annotate.
# usage: tools/glint_debug_plugin.sh <build dir> <out .so>
# (the source tree is the one the build dir was configured from)
set -euo pipefail
build=$(cd "${1:-build}" && pwd)
out=${2:-/tmp/glint_debug/libglimmer_closures.so}
mkdir -p "$(dirname "$out")"
obj="$(dirname "$out")/glint_g.o"
cmd=$(python3 - "$build" <<'PY'
import json, sys
for e in json.load(open(sys.argv[1] + '/compile_commands.json')):
    if e['file'].endswith('plugin/closures/glint.cpp'):
        print(e['command'])
PY
)
cmd=$(sed -E 's/ -o [^ ]+ / -o OBJ_OUT /; s/ -O3 / -O3 -g /' <<<"$cmd")
(cd "$build" && eval "${cmd/OBJ_OUT/$obj}")
objs=$(grep -m1 '^build libglimmer_closures.so:' "$build/build.ninja" | sed -E 's/^build [^:]+: [^ ]+ //; s/ \|\|.*//')
objs=$(sed "s#plugin/CMakeFiles/glimmer_closure_objects.dir/closures/glint.cpp.o#$obj#" <<<"$objs")
(cd "$build" && /usr/bin/c++ -fPIC -O3 -DNDEBUG -Wl,--no-undefined -shared -Wl,-soname,libglimmer_closures.so -o "$out" $objs)
echo "$out"
