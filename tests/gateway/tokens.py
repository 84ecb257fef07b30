# What an outside Zenoh client (Python's eclipse-zenoh) sees of a gateway's cells:
# the liveliness tokens under vl/cells/*, as a JSON list of their keys.
# Usage: tokens.py tcp/HOST:PORT
import sys, json, zenoh
conf = zenoh.Config()
conf.insert_json5("mode", '"client"')
conf.insert_json5("connect/endpoints", json.dumps([sys.argv[1]]))
conf.insert_json5("scouting/multicast/enabled", "false")
with zenoh.open(conf) as s:
    replies = s.liveliness().get("vl/cells/*", timeout=3.0)
    names = sorted(str(r.ok.key_expr) for r in replies if r.ok is not None)
    print(json.dumps(names))
