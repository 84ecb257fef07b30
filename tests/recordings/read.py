"""Reads a vl recording with the `mcap` package, independently of vl, and
prints what it found as JSON: each channel's schema and count, whether log
times never go back, how many camera images decode as JPEG, and the run's
summary as recorded."""

import base64
import json
import sys

from mcap.reader import make_reader

path = sys.argv[1]
topics = {}
last = 0
monotonic = True
jpegs = 0
summary = None
feedback_t = []
with open(path, "rb") as f:
    reader = make_reader(f)
    for schema, channel, message in reader.iter_messages(log_time_order=False):
        entry = topics.setdefault(
            channel.topic,
            {"schema": schema.name if schema else "", "encoding": channel.message_encoding, "count": 0},
        )
        entry["count"] += 1
        if message.log_time < last:
            monotonic = False
        last = message.log_time
        data = json.loads(message.data)
        if channel.topic == "/camera":
            jpeg = base64.b64decode(data["data"])
            if jpeg[:2] == b"\xff\xd8" and jpeg[-2:] == b"\xff\xd9" and data["format"] == "jpeg":
                jpegs += 1
        elif channel.topic == "/summary":
            summary = data["summary"]
        elif channel.topic == "/feedback":
            feedback_t.append(message.log_time)
print(json.dumps({
    "topics": topics,
    "monotonic": monotonic,
    "jpegs": jpegs,
    "summary": summary,
    "feedback_seconds": (feedback_t[-1] - feedback_t[0]) / 1e9 if feedback_t else 0.0,
}))
