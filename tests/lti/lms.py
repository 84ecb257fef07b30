"""An LMS platform written from the LTI 1.3 specifications with PyJWT and
cryptography, nothing of vl's: the outside end of tests/lti.rs.

It serves what a platform serves (its JWKS, the OIDC authorization
endpoint, the OAuth2 token endpoint checking the tool's client assertion
against the tool's JWKS, a line item's scores and a course's roster) and
takes commands, one JSON object a line on stdin, answering one JSON line
on stdout:

  {"cmd": "tool", "url": TOOL}               where the tool is
  {"cmd": "launch", "role": R, ...}          a launch, as a browser makes it
  {"cmd": "deep_link"}                       an instructor's deep linking
  {"cmd": "scores"}                          the scores received so far
  {"cmd": "fail_scores", "n": N}             refuse the next N score posts (503)
  {"cmd": "prepare", "role": R}              a course page whose form
                                             launches the lab in a browser
"""

import json
import re
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
import uuid
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer

import jwt
from cryptography.hazmat.primitives.asymmetric import rsa
from jwt import PyJWKClient

CLIENT_ID = "vl-tool-1"
DEPLOYMENT = "deployment-1"
KID = "platform-key-1"
COURSE = {"id": "course-7", "title": "Mobile robotics 101"}
MEMBERS = [
    {"user_id": "learner-1", "name": "Ada Learner", "status": "Active",
     "roles": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"]},
    {"user_id": "teacher-1", "name": "Tom Teacher", "status": "Active",
     "roles": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"]},
]
ROLES = {
    "learner": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner"],
    "instructor": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Instructor"],
    # A learner of this course who teaches elsewhere: an institution's role.
    "learner_teaching_elsewhere": ["http://purl.imsglobal.org/vocab/lis/v2/membership#Learner",
                                   "http://purl.imsglobal.org/vocab/lis/v2/institution/person#Instructor"],
}
SUBS = {"learner": "learner-1", "instructor": "teacher-1", "learner_teaching_elsewhere": "learner-2"}
NAMES = {"learner": "Ada Learner", "instructor": "Tom Teacher", "learner_teaching_elsewhere": "Eve Learner"}
# What the course's link asks for, unless a launch says otherwise.
CUSTOM = {"experiment": "navigation", "goal": "720,80"}

KEY = rsa.generate_private_key(public_exponent=65537, key_size=2048)
OTHER_KEY = rsa.generate_private_key(public_exponent=65537, key_size=2048)

state = {"tool": None, "scores": [], "tokens": {}, "token_errors": [], "auth": {}, "pages": {},
         "fail_scores": 0, "refused_scores": 0}


def jwks():
    jwk = json.loads(jwt.algorithms.RSAAlgorithm.to_jwk(KEY.public_key()))
    jwk.update({"kid": KID, "alg": "RS256", "use": "sig"})
    return {"keys": [jwk]}


class Platform(BaseHTTPRequestHandler):
    def log_message(self, *args):
        pass

    def answer(self, status, body, kind="application/json"):
        data = body if isinstance(body, bytes) else json.dumps(body).encode()
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.end_headers()
        self.wfile.write(data)

    def do_GET(self):
        url = urllib.parse.urlparse(self.path)
        if url.path == "/jwks":
            return self.answer(200, jwks())
        if url.path == "/auth":
            # The authorization endpoint: the test reads what the tool asked.
            query = dict(urllib.parse.parse_qsl(url.query))
            state["auth"][query.get("state")] = query
            return self.answer(200, {"ok": True})
        if url.path == "/course":
            # A course page as an LMS makes it: its form posts the launch.
            token, login_state = state["pages"][dict(urllib.parse.parse_qsl(url.query))["k"]]
            page = ('<!doctype html><title>Mobile robotics 101</title>'
                    '<form id="launch" method="post" action="%s/lti/launch">'
                    '<input type="hidden" name="id_token" value="%s">'
                    '<input type="hidden" name="state" value="%s"></form>'
                    '<script>document.getElementById("launch").submit()</script>'
                    % (state["tool"], token, login_state))
            return self.answer(200, page.encode(), "text/html")
        if url.path == "/memberships":
            if not self.bearer("https://purl.imsglobal.org/spec/lti-nrps/scope/contextmembership.readonly"):
                return self.answer(401, {"error": "no valid token"})
            return self.answer(200, {"id": self.path, "context": COURSE, "members": MEMBERS},
                               "application/vnd.ims.lti-nrps.v2.membershipcontainer+json")
        self.answer(404, {"error": "no such page"})

    def bearer(self, scope):
        given = self.headers.get("Authorization", "")
        token = given[len("Bearer "):] if given.startswith("Bearer ") else None
        return token is not None and scope in state["tokens"].get(token, "").split()

    def do_POST(self):
        length = int(self.headers.get("Content-Length", "0"))
        body = self.rfile.read(length)
        url = urllib.parse.urlparse(self.path)
        if url.path == "/token":
            return self.token(dict(urllib.parse.parse_qsl(body.decode())))
        item = re.fullmatch(r"/lineitems/(\d+)/lineitem/scores", url.path)
        if item:
            ok = self.bearer("https://purl.imsglobal.org/spec/lti-ags/scope/score")
            kind = self.headers.get("Content-Type", "")
            if not ok:
                return self.answer(401, {"error": "no valid token"})
            if kind != "application/vnd.ims.lis.v1.score+json":
                return self.answer(415, {"error": "not a score: " + kind})
            if state["fail_scores"] > 0:
                state["fail_scores"] -= 1
                state["refused_scores"] += 1
                return self.answer(503, {"error": "the gradebook is down for maintenance"})
            score = json.loads(body)
            score["received_at"] = time.time()
            score["lineitem"] = int(item.group(1))
            state["scores"].append(score)
            return self.answer(200, {})
        self.answer(404, {"error": "no such page"})

    def token(self, form):
        """OAuth2 client credentials with a JWT assertion (RFC 7523), the
        assertion checked against the tool's published keys."""
        try:
            assert form.get("grant_type") == "client_credentials", "grant_type"
            assert form.get("client_assertion_type") == \
                "urn:ietf:params:oauth:client-assertion-type:jwt-bearer", "assertion type"
            assertion = form["client_assertion"]
            keys = PyJWKClient(state["tool"] + "/lti/jwks")
            key = keys.get_signing_key_from_jwt(assertion)
            claims = jwt.decode(assertion, key.key, algorithms=["RS256"],
                                audience=issuer() + "/token",
                                options={"require": ["iss", "sub", "aud", "exp", "iat", "jti"]})
            assert claims["iss"] == CLIENT_ID and claims["sub"] == CLIENT_ID, "iss/sub"
        except Exception as e:  # noqa: BLE001 - every failure is the tool's to see
            state["token_errors"].append(repr(e))
            return self.answer(400, {"error": "invalid_client", "why": repr(e)})
        token = str(uuid.uuid4())
        state["tokens"][token] = form.get("scope", "")
        self.answer(200, {"access_token": token, "token_type": "Bearer", "expires_in": 3600,
                          "scope": form.get("scope", "")})


SERVER = ThreadingHTTPServer(("127.0.0.1", 0), Platform)


def issuer():
    return "http://127.0.0.1:%d" % SERVER.server_address[1]


def post_form(url, fields):
    data = urllib.parse.urlencode(fields).encode()
    request = urllib.request.Request(url, data=data, method="POST")
    request.add_header("Content-Type", "application/x-www-form-urlencoded")
    return fetch(request)


def fetch(request):
    class Stay(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args):
            return None
    opener = urllib.request.build_opener(Stay)
    try:
        with opener.open(request, timeout=20) as r:
            return r.status, r.headers, r.read().decode()
    except urllib.error.HTTPError as e:
        return e.code, e.headers, e.read().decode()


def login(message_hint="resource", method="GET"):
    """The third-party login initiation (GET or POST, as platforms do),
    then the tool's redirect to /auth."""
    fields = {
        "iss": issuer(), "login_hint": "hint-1", "target_link_uri": state["tool"] + "/lti/launch",
        "lti_message_hint": message_hint, "client_id": CLIENT_ID, "lti_deployment_id": DEPLOYMENT,
    }
    if method == "POST":
        status, headers, body = post_form(state["tool"] + "/lti/login", fields)
    else:
        query = urllib.parse.urlencode(fields)
        status, headers, body = fetch(urllib.request.Request(state["tool"] + "/lti/login?" + query))
    if status != 303 and status != 302 and status != 307:
        return None, {"status": status, "body": body}
    location = headers.get("Location")
    auth = dict(urllib.parse.parse_qsl(urllib.parse.urlparse(location).query))
    checks = {
        "to_auth_url": location.startswith(issuer() + "/auth?"),
        "openid": auth.get("scope") == "openid" and auth.get("response_type") == "id_token",
        "form_post": auth.get("response_mode") == "form_post",
        "client_id": auth.get("client_id") == CLIENT_ID,
        "redirect_uri": auth.get("redirect_uri") == state["tool"] + "/lti/launch",
        "login_hint": auth.get("login_hint") == "hint-1",
        "state_and_nonce": bool(auth.get("state")) and bool(auth.get("nonce")),
    }
    return auth, checks


def id_token(auth, role, message_type="LtiResourceLinkRequest", tamper=None, custom=None, link=1):
    now = int(time.time())
    claims = {
        "iss": issuer(), "aud": CLIENT_ID, "azp": CLIENT_ID, "sub": SUBS[role],
        "iat": now, "exp": now + 300, "nonce": auth["nonce"],
        "name": NAMES[role],
        "https://purl.imsglobal.org/spec/lti/claim/message_type": message_type,
        "https://purl.imsglobal.org/spec/lti/claim/version": "1.3.0",
        "https://purl.imsglobal.org/spec/lti/claim/deployment_id": DEPLOYMENT,
        "https://purl.imsglobal.org/spec/lti/claim/target_link_uri": state["tool"] + "/lti/launch",
        "https://purl.imsglobal.org/spec/lti/claim/roles": ROLES[role],
        "https://purl.imsglobal.org/spec/lti/claim/context": COURSE,
        "https://purl.imsglobal.org/spec/lti/claim/resource_link": {"id": "link-%d" % link, "title": "Lab %d" % link},
        "https://purl.imsglobal.org/spec/lti/claim/custom": CUSTOM if custom is None else custom,
        "https://purl.imsglobal.org/spec/lti-ags/claim/endpoint": {
            "scope": ["https://purl.imsglobal.org/spec/lti-ags/scope/lineitem",
                      "https://purl.imsglobal.org/spec/lti-ags/scope/score"],
            "lineitem": issuer() + "/lineitems/%d/lineitem" % link,
            "lineitems": issuer() + "/lineitems",
        },
        "https://purl.imsglobal.org/spec/lti-nrps/claim/namesroleservice": {
            "context_memberships_url": issuer() + "/memberships",
            "service_versions": ["2.0"],
        },
    }
    if message_type == "LtiDeepLinkingRequest":
        claims["https://purl.imsglobal.org/spec/lti-dl/claim/deep_linking_settings"] = {
            "deep_link_return_url": issuer() + "/deep-link-return",
            "accept_types": ["ltiResourceLink"],
            "accept_presentation_document_targets": ["iframe", "window"],
            "data": "opaque-data-42",
        }
    key = KEY
    if tamper == "signature":
        key = OTHER_KEY
    elif tamper == "audience":
        claims["aud"] = "someone-else"
        claims.pop("azp")
    elif tamper == "expired":
        claims["iat"] = now - 3600
        claims["exp"] = now - 1800
    elif tamper == "deployment":
        claims["https://purl.imsglobal.org/spec/lti/claim/deployment_id"] = "deployment-unknown"
    return jwt.encode(claims, key, algorithm="RS256", headers={"kid": KID})


def launch(command):
    role = command.get("role", "learner")
    auth, checks = login()
    if auth is None:
        return {"login": checks}
    token = id_token(auth, role, tamper=command.get("tamper"), custom=command.get("custom"),
                     link=command.get("link", 1))
    status, headers, body = post_form(state["tool"] + "/lti/launch",
                                      {"id_token": token, "state": auth["state"]})
    result = {"login": checks, "status": status, "body": body,
              "csp": headers.get("Content-Security-Policy", "")}
    if command.get("replay"):
        # The same token again, on a new login of its own: its nonce is used.
        auth2, _ = login()
        status2, _, body2 = post_form(state["tool"] + "/lti/launch",
                                      {"id_token": token, "state": auth2["state"]})
        # And the same state again: that login is over.
        status3, _, body3 = post_form(state["tool"] + "/lti/launch",
                                      {"id_token": token, "state": auth["state"]})
        result["replayed"] = {"status": status2, "body": body2}
        result["state_again"] = {"status": status3, "body": body3}
    return result


def prepare(command):
    auth, _ = login()
    key = str(len(state["pages"]))
    state["pages"][key] = (id_token(auth, command.get("role", "learner")), auth["state"])
    return {"course": issuer() + "/course?k=" + key}


def deep_link(command):
    auth, checks = login("deep-link", "POST")
    if auth is None:
        return {"login": checks}
    token = id_token(auth, command.get("role", "instructor"), "LtiDeepLinkingRequest")
    status, _, page = post_form(state["tool"] + "/lti/launch", {"id_token": token, "state": auth["state"]})
    if status != 200 or "/lti/deep-link" not in page:
        return {"status": status, "page": page}
    session = page.split('name="session" value="')[1].split('"')[0]
    status, headers, page = post_form(state["tool"] + "/lti/deep-link", {
        "session": session, "title": "Maze run", "experiment": "navigation",
        "goal_x": "720", "goal_y": "80"})
    action = page.split('action="')[1].split('"')[0].replace("&amp;", "&")
    response = page.split('name="JWT" value="')[1].split('"')[0]
    keys = PyJWKClient(state["tool"] + "/lti/jwks")
    key = keys.get_signing_key_from_jwt(response)
    claims = jwt.decode(response, key.key, algorithms=["RS256"], audience=issuer(),
                        options={"require": ["iss", "aud", "exp", "iat", "nonce"]})
    return {"status": status, "action": action, "expected_action": issuer() + "/deep-link-return",
            "csp": headers.get("Content-Security-Policy", ""), "claims": claims,
            "header": jwt.get_unverified_header(response)}


def main():
    threading.Thread(target=SERVER.serve_forever, daemon=True).start()
    print(json.dumps({"issuer": issuer(), "client_id": CLIENT_ID, "deployment_id": DEPLOYMENT,
                      "auth_url": issuer() + "/auth", "token_url": issuer() + "/token",
                      "jwks_url": issuer() + "/jwks"}), flush=True)
    for line in sys.stdin:
        command = json.loads(line)
        try:
            if command["cmd"] == "tool":
                state["tool"] = command["url"].rstrip("/")
                answer = {"ok": True}
            elif command["cmd"] == "launch":
                answer = launch(command)
            elif command["cmd"] == "deep_link":
                answer = deep_link(command)
            elif command["cmd"] == "fail_scores":
                state["fail_scores"] = command["n"]
                answer = {"ok": True}
            elif command["cmd"] == "prepare":
                answer = prepare(command)
            elif command["cmd"] == "scores":
                answer = {"scores": state["scores"], "token_errors": state["token_errors"],
                          "refused": state["refused_scores"]}
            else:
                answer = {"error": "unknown command"}
        except Exception as e:  # noqa: BLE001 - the test shows what failed
            answer = {"error": repr(e)}
        print(json.dumps(answer), flush=True)


if __name__ == "__main__":
    main()
