"""The schema snapshot shipped in the addon equals `glimmer describe --json`
for every closure both list; closures the snapshot marks "dso" must still
exist in the DSO, and the abi version must match. Closures marked "planned"
(defined by the addon before the DSO lists them) are compared as soon as the
DSO lists them, so a mismatch there asks for a snapshot refresh
(`python3 tools/make_addon_zip.py --refresh-schema`)."""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import addon_test_util as util  # noqa: E402

check = util.check
opts = util.args()
glimmer = os.environ.get("GLIMMER_EXECUTABLE", "")
check(glimmer and os.path.isfile(glimmer), "the glimmer executable is needed (--glimmer)")
mod = util.enable_addon()
live = mod.schema.describe_live(glimmer)
snapshot = mod.schema.load_snapshot()
check(snapshot["plugin"]["abi_version"] == live["plugin"]["abi_version"], "abi version of the snapshot")


def same(a, b, where):
    if isinstance(a, float) or isinstance(b, float):
        check(isinstance(a, (int, float)) and isinstance(b, (int, float)) and
              math.isclose(a, b, rel_tol=1e-6, abs_tol=1e-12), "%s: %r != %r" % (where, a, b))
    elif isinstance(a, list):
        check(isinstance(b, list) and len(a) == len(b), "%s: %r != %r" % (where, a, b))
        for i, (x, y) in enumerate(zip(a, b)):
            same(x, y, "%s[%d]" % (where, i))
    elif isinstance(a, dict):
        check(isinstance(b, dict) and set(a) == set(b), "%s: keys %s != %s" % (where, sorted(a), sorted(b)))
        for key in a:
            same(a[key], b[key], "%s.%s" % (where, key))
    else:
        check(a == b, "%s: %r != %r" % (where, a, b))


live_by_name = {c["name"]: c for c in live["closures"]}
compared = []
for closure in snapshot["closures"]:
    name = closure["name"]
    expected = {k: v for k, v in closure.items() if k != "source"}
    if closure["source"] == "dso":
        check(name in live_by_name, "snapshot closure '%s' is no longer in the DSO: refresh the snapshot" % name)
    if name in live_by_name:
        same(live_by_name[name], expected, "closure %s (refresh with tools/make_addon_zip.py --refresh-schema)"
             % name)
        compared.append(name)
    else:
        print("note: '%s' is defined by the snapshot only (%s); the DSO does not list it yet" % (name,
                                                                                                closure["source"]))
check(compared, "at least one closure compared")
missing = sorted(set(live_by_name) - {c["name"] for c in snapshot["closures"]})
if missing:
    print("note: DSO closures without a snapshot entry (no Blender node needs them): %s" % missing)
print("compared with the DSO:", compared)
util.done("test_schema_snapshot")
