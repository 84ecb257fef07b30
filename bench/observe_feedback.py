"""An observer of a vl Host, from outside vl: says hello, answers pings, and
times the gaps between the feedback it gets from a run's `started` to its
`done` (or SECONDS). Prints their count, p50, p99 and most, in ms, as JSON.
    python3 bench/observe_feedback.py ws://HOST:PORT/ SECONDS"""
import asyncio
import json
import sys
import time

import websockets


async def main(url, seconds):
    async with websockets.connect(url, max_size=None) as ws:
        await ws.send(json.dumps({"type": "hello", "protocol": 1, "role": "observer"}))
        gaps, last, running = [], None, False
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            try:
                m = await asyncio.wait_for(ws.recv(), timeout=1)
            except asyncio.TimeoutError:
                continue
            if isinstance(m, bytes):
                continue
            m = json.loads(m)
            kind = m.get("type")
            if kind == "ping":
                await ws.send(json.dumps({"type": "pong", "t": m["t"]}))
            elif kind == "started":
                running, last = True, None
            elif kind == "done":
                break
            elif kind == "feedback" and running:
                now = time.monotonic()
                if last is not None:
                    gaps.append((now - last) * 1000)
                last = now
        gaps.sort()

        def at(q):
            return gaps[min(len(gaps) - 1, int(q * (len(gaps) - 1)))] if gaps else None

        print(json.dumps({"n": len(gaps), "p50_ms": at(0.5), "p99_ms": at(0.99),
                          "max_ms": gaps[-1] if gaps else None}))


asyncio.run(main(sys.argv[1], float(sys.argv[2])))
