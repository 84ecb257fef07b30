# Someone else on a gateway's Zenoh network, with Python's eclipse-zenoh (nothing
# of vl's): a stranger with no certificate, one with another authority's, or a
# member with the credentials `vl gateway issue` wrote (a TOML file).
#
# Usage: outside.py ENDPOINT [CREDENTIALS.toml [INFO.json]]
#
# It joins (or fails to), then for a few seconds tries what a hostile member
# would: reads every cell's links, lists the cells, forges a hello from the
# lab's administrator on cells a and b's links, rogue cell tokens, a 9 MB frame and a
# phishing message on cell a's keys. With INFO.json (a cell's info, named for
# the member) it also says it is a cell on its own keys, as a member may: the
# control that shows the rest was refused, not lost. It prints what it got, as
# JSON.
import json
import sys
import time
import tomllib
import base64

import zenoh

SECONDS = 3.0


def config(endpoint, credentials):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("connect/timeout_ms", "3000")
    conf.insert_json5("connect/exit_on_failure", "true")
    conf.insert_json5("scouting/multicast/enabled", "false")
    if credentials:
        with open(credentials, "rb") as f:
            c = tomllib.load(f)
        b64 = lambda pem: base64.b64encode(pem.encode()).decode()
        tls = {
            "root_ca_certificate_base64": b64(c["authority"]),
            "connect_certificate_base64": b64(c["certificate"]),
            "connect_private_key_base64": b64(c["key"]),
            "enable_mtls": True,
        }
        conf.insert_json5("transport/link/tls", json.dumps(tls))
    return conf


def main():
    endpoint = sys.argv[1]
    credentials = sys.argv[2] if len(sys.argv) > 2 else None
    info = json.loads(open(sys.argv[3]).read()) if len(sys.argv) > 3 else None
    try:
        # Two sessions: one reads, one forges (a session hears its own puts).
        reader = zenoh.open(config(endpoint, credentials))
        session = zenoh.open(config(endpoint, credentials))
    except Exception as e:  # the network refused us
        print(json.dumps({"joined": False, "why": str(e)}), flush=True)
        return
    read = []
    subs = [
        reader.declare_subscriber(key, lambda s: read.append(str(s.key_expr)))
        for key in ["vl/cells/*/links/**", "vl/cells/a/**", "vl/**"]
    ]
    admin = {"identity": {"kind": "account", "name": "root", "role": "admin"}, "may_drive": True}
    hello = json.dumps({"type": "hello", "admitted": admin, "protocol": 1, "role": "operator", "resume": None})
    tokens = [session.liveliness().declare_token(f"vl/cells/{k}") for k in ["fake", "a/links/forged"]]
    tokens += [session.liveliness().declare_token(f"vl/cells/rogue-{n}") for n in range(50)]
    own = None
    if info is not None:
        own = session.liveliness().declare_token(f"vl/cells/{info['name']}")
    frame = b"\xff\xd8" + b"\x00" * (9 << 20)
    phishing = json.dumps({"type": "error", "code": "unauthorized", "message": "log in again at http://evil.example/"})
    began = time.monotonic()
    forged = 0
    while time.monotonic() - began < SECONDS:
        for cell in ["a", "b"]:
            session.put(f"vl/cells/{cell}/links/forged/up", hello)
        session.put("vl/cells/a/messages", phishing)
        session.put("vl/cells/a/info", json.dumps({"name": "a", "experiments": [], "mounted": None, "lab": "ready", "run": None, "operator": None, "line": 0}))
        if forged % 10 == 0:
            session.put("vl/cells/a/frames", frame)
        if info is not None:
            session.put(f"vl/cells/{info['name']}/info", json.dumps(info))
        forged += 1
        time.sleep(0.02)
    listed = sorted(str(r.ok.key_expr) for r in reader.liveliness().get("vl/cells/*", timeout=2.0) if r.ok is not None)
    for s in subs:
        s.undeclare()
    print(json.dumps({"joined": True, "read": len(read), "read_keys": sorted(set(read))[:20], "listed": listed, "forged": forged}), flush=True)
    # Stay while the caller looks at the gateway: until stdin closes.
    sys.stdin.read()
    del own, tokens
    session.close()
    reader.close()


main()
