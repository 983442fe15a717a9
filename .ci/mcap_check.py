"""Reads a grop mission log with the PyPI `mcap` reader only and checks what a stranger's tool
needs: every channel has a JSON Schema and JSON messages, every message decodes with `json` and
carries its schema's properties, the camera frames are Foxglove RawImages whose data is the
image, and the topics a mission must have are there. Prints one line per channel."""
import base64
import json
import sys

from mcap.reader import make_reader

EXPECTED = {
    "/camera/frame", "/heatmaps", "/plan/task", "/plan/request", "/base/pose", "/base/state",
    "/arm/state", "/arm/io", "/events", "/health", "/can", "/timing/decision", "/load/request", "/operator/enable",
}


def main(path):
    failures = []
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        if summary is None:
            print("no summary: the log was not finished")
            return 1
        channels = summary.channels
        schemas = summary.schemas
        counts = summary.statistics.channel_message_counts
        topics = {c.topic: c for c in channels.values()}
        missing = EXPECTED - set(topics)
        if missing:
            failures.append(f"missing topics: {sorted(missing)}")
        properties = {}
        for cid, c in channels.items():
            s = schemas[c.schema_id]
            if c.message_encoding != "json" or s.encoding != "jsonschema":
                failures.append(f"{c.topic}: encodings {c.message_encoding}/{s.encoding}")
                continue
            schema = json.loads(s.data)
            properties[cid] = set(schema["properties"])
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        if "grop.mission" not in metadata or "map" not in metadata["grop.mission"]:
            failures.append("no grop.mission metadata with the map")
        log_format = metadata.get("grop.log", {}).get("log_format", "")
        if not log_format.isdigit() or int(log_format) < 2:
            failures.append(f"grop.log metadata: log_format {log_format!r} (expected 2 or later)")
        seen = {}
        for schema, channel, message in reader.iter_messages():
            doc = json.loads(message.data)
            missing_keys = properties.get(channel.id, set()) - set(doc)
            if missing_keys:
                failures.append(f"{channel.topic}: message lacks {sorted(missing_keys)}")
                break
            if channel.topic == "/camera/frame":
                if schema.name != "foxglove.RawImage":
                    failures.append(f"camera schema {schema.name}")
                data = base64.b64decode(doc["data"])
                if len(data) != doc["step"] * doc["height"]:
                    failures.append(f"camera frame of {len(data)} bytes, not step x height")
            seen[channel.topic] = seen.get(channel.topic, 0) + 1
        for cid, c in sorted(channels.items(), key=lambda kv: kv[1].topic):
            n = seen.get(c.topic, 0)
            print(f"  {c.topic:18s} {schemas[c.schema_id].name:20s} {n:7d} messages")
            if n != counts.get(cid, -1):
                failures.append(f"{c.topic}: {n} decoded, summary says {counts.get(cid)}")
    for f in failures:
        print("FAIL", f)
    print(f"mcap-check: {len(topics)} channels, {sum(seen.values())} messages, "
          f"{len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
