"""An outside client of a vl Host over wss://: Python's websockets and ssl.

Fetches the Host's certificate, checks its SHA-256 against the pin the Host
printed, trusts exactly that certificate, says hello as an observer and
prints the welcome's session number.

usage: client.py PORT PIN
"""
import asyncio
import hashlib
import json
import ssl
import sys

import websockets

port, pin = int(sys.argv[1]), sys.argv[2]
pem = ssl.get_server_certificate(("127.0.0.1", port))
if hashlib.sha256(ssl.PEM_cert_to_DER_cert(pem)).hexdigest() != pin:
    sys.exit("the certificate is not the pinned one")
trust = ssl.create_default_context(cadata=pem)


async def main():
    async with websockets.connect(f"wss://localhost:{port}", ssl=trust) as ws:
        await ws.send(json.dumps({"type": "hello", "protocol": 1, "role": "observer"}))
        while True:
            message = await asyncio.wait_for(ws.recv(), 10)
            if isinstance(message, bytes):
                continue
            message = json.loads(message)
            if message["type"] == "welcome":
                print("welcome", message["session"])
                return


asyncio.run(main())
