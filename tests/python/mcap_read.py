"""Reads an MCAP file with the reference `mcap` reader and prints one JSON object: per channel
its message count, encoding and schema, plus the last message of a few channels decoded.

Usage: python mcap_read.py FILE.mcap
"""

import json
import sys

from mcap.reader import make_reader

path = sys.argv[1]
channels = {}
last = {}
with open(path, "rb") as stream:
    reader = make_reader(stream)
    header = reader.get_header()
    for schema, channel, message in reader.iter_messages(log_time_order=True):
        entry = channels.setdefault(
            channel.topic,
            {
                "count": 0,
                "message_encoding": channel.message_encoding,
                "schema_name": schema.name if schema else None,
                "schema_encoding": schema.encoding if schema else None,
            },
        )
        entry["count"] += 1
        if channel.message_encoding == "json":
            last[channel.topic] = json.loads(message.data)
        elif channel.topic == "/camera":
            # foxglove.CompressedImage in protobuf: the JPEG is in field 3 (bytes); check the
            # JPEG start marker is in there without a protobuf library.
            last["/camera"] = {"bytes": len(message.data), "has_jpeg": b"\xff\xd8\xff" in message.data}
    summary = reader.get_summary()

print(
    json.dumps(
        {
            "profile": header.profile,
            "library": header.library,
            "channels": channels,
            "last": last,
            "summary_message_count": summary.statistics.message_count if summary and summary.statistics else None,
        }
    )
)
