"""Reads a grop mission log with the PyPI `mcap` reader only and checks what a stranger's tool
needs: every channel has a JSON Schema and JSON messages, every message decodes with `json` and
carries its schema's properties, the camera frames are Foxglove RawImages whose data is the
image, and the topics a mission must have are there. Prints one line per channel.

Every message of a channel in one of Foxglove's well-known schemas (`foxglove.*`) is also parsed
into that schema's protobuf message from the PyPI `foxglove-schemas-protobuf` package with
`google.protobuf.json_format.ParseDict`, which refuses a field the schema lacks and a value of
the wrong type. Foxglove's JSON form writes times and durations as {"sec", "nsec"} where the
protobuf JSON form wants strings: those are converted first, nothing else. The camera frames
carry four fields of ours beyond RawImage's (GROP_RAW_IMAGE_EXTRAS): those are checked to be
there and set aside. The channel's JSON Schema must list exactly the protobuf message's fields."""
import base64
import datetime
import importlib
import json
import sys

from google.protobuf import json_format
from mcap.reader import make_reader

EXPECTED = {
    "/camera/frame", "/heatmaps", "/plan/task", "/plan/request", "/base/pose", "/base/state",
    "/arm/state", "/arm/io", "/events", "/health", "/can", "/timing/decision", "/load/request", "/operator/enable",
    "/tf", "/scene", "/plan/path", "/base/path", "/heatmaps/grid", "/events/log", "/scan",
    "/world/truth", "/psi/views",
}
# The well-known schema each of these topics must have.
WELL_KNOWN = {
    "/camera/frame": "foxglove.RawImage", "/tf": "foxglove.FrameTransforms",
    "/scene": "foxglove.SceneUpdate", "/plan/path": "foxglove.PosesInFrame",
    "/base/path": "foxglove.PosesInFrame", "/heatmaps/grid": "foxglove.Grid",
    "/events/log": "foxglove.Log", "/scan": "foxglove.PointCloud",
    "/psi/views": "foxglove.RawImage",
}
# Frames /tf must name at least once (the HIL world's truth beside the estimate).
FRAMES = {"map", "odom", "base_link", "arm_base", "arm_link6", "truth_base_link"}
GROP_RAW_IMAGE_EXTRAS = {"grop_frame_id", "metres_per_px", "left_x_m", "top_y_m"}


def proto_class(schema_name):
    short = schema_name.split(".", 1)[1]
    module = importlib.import_module(f"foxglove_schemas_protobuf.{short}_pb2")
    return getattr(module, short)


def to_proto_json(value, descriptor):
    """Foxglove's JSON form -> protobuf's JSON form: times and durations become strings."""
    if not isinstance(value, dict):
        return value
    out = {}
    for key, v in value.items():
        field = descriptor.fields_by_name.get(key)
        kind = field.message_type.full_name if field is not None and field.message_type else None
        if kind in ("google.protobuf.Timestamp", "google.protobuf.Duration") and isinstance(v, dict):
            if set(v) != {"sec", "nsec"} or not all(isinstance(x, int) for x in v.values()):
                raise ValueError(f"{key}: {v!r} is not {{sec, nsec}}")
            if kind == "google.protobuf.Duration":
                out[key] = f"{v['sec']}.{v['nsec']:09d}s"
            else:
                t = datetime.datetime.fromtimestamp(v["sec"], datetime.timezone.utc)
                out[key] = t.strftime("%Y-%m-%dT%H:%M:%S") + f".{v['nsec']:09d}Z"
        elif kind is not None and isinstance(v, list):
            out[key] = [to_proto_json(x, field.message_type) for x in v]
        elif kind is not None:
            out[key] = to_proto_json(v, field.message_type)
        else:
            out[key] = v
    return out


def check_well_known(topic, schema_name, doc):
    """Parses one message into the protobuf message of its schema; returns an error or None."""
    cls = proto_class(schema_name)
    if topic == "/camera/frame":
        missing = GROP_RAW_IMAGE_EXTRAS - set(doc)
        if missing:
            return f"lacks {sorted(missing)}"
        doc = {k: v for k, v in doc.items() if k not in GROP_RAW_IMAGE_EXTRAS}
    try:
        message = json_format.ParseDict(to_proto_json(doc, cls.DESCRIPTOR), cls())
    except (json_format.ParseError, ValueError) as e:
        return f"not a {schema_name}: {e}"
    if schema_name == "foxglove.Grid":
        if message.row_stride == 0 or len(message.data) % message.row_stride \
                or message.row_stride < message.column_count * message.cell_stride:
            return f"grid data of {len(message.data)} bytes, row stride {message.row_stride}"
    if schema_name == "foxglove.PointCloud":
        if message.point_stride < 12 or len(message.data) % message.point_stride:
            return f"point cloud data of {len(message.data)} bytes, stride {message.point_stride}"
    if schema_name == "foxglove.RawImage":
        if message.step == 0 or len(message.data) != message.step * message.height:
            return f"image data of {len(message.data)} bytes, step {message.step} x height {message.height}"
    if schema_name == "foxglove.SceneUpdate" and not message.entities:
        return "a scene without entities"
    if schema_name == "foxglove.FrameTransforms" and not message.transforms:
        return "no transforms"
    return None


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
            wanted = WELL_KNOWN.get(c.topic)
            if wanted is not None and s.name != wanted:
                failures.append(f"{c.topic}: schema {s.name}, expected {wanted}")
            if s.name.startswith("foxglove."):
                fields = {f.name for f in proto_class(s.name).DESCRIPTOR.fields}
                extra = properties[cid] - fields - (GROP_RAW_IMAGE_EXTRAS if c.topic == "/camera/frame" else set())
                if extra or fields - properties[cid]:
                    failures.append(f"{c.topic}: JSON Schema fields {sorted(properties[cid])} "
                                    f"are not {s.name}'s {sorted(fields)}")
        metadata = {m.name: m.metadata for m in reader.iter_metadata()}
        if "grop.mission" not in metadata or "map" not in metadata["grop.mission"]:
            failures.append("no grop.mission metadata with the map")
        log_format = metadata.get("grop.log", {}).get("log_format", "")
        if not log_format.isdigit() or int(log_format) < 2:
            failures.append(f"grop.log metadata: log_format {log_format!r} (expected 2 or later)")
        seen = {}
        checked = {}
        frames = set()
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
            if channel.topic == "/tf":
                frames.update(t["child_frame_id"] for t in doc["transforms"])
                frames.update(t["parent_frame_id"] for t in doc["transforms"])
            if schema.name.startswith("foxglove."):
                error = check_well_known(channel.topic, schema.name, doc)
                if error:
                    failures.append(f"{channel.topic} message {seen.get(channel.topic, 0)}: {error}")
                    break
                checked[channel.topic] = checked.get(channel.topic, 0) + 1
            seen[channel.topic] = seen.get(channel.topic, 0) + 1
        for cid, c in sorted(channels.items(), key=lambda kv: kv[1].topic):
            n = seen.get(c.topic, 0)
            print(f"  {c.topic:18s} {schemas[c.schema_id].name:20s} {n:7d} messages")
            if n != counts.get(cid, -1):
                failures.append(f"{c.topic}: {n} decoded, summary says {counts.get(cid)}")
        if FRAMES - frames:
            failures.append(f"/tf never names {sorted(FRAMES - frames)}")
        for topic in WELL_KNOWN:
            if checked.get(topic, 0) == 0:
                failures.append(f"{topic}: no message parsed as {WELL_KNOWN[topic]}")
    for f in failures:
        print("FAIL", f)
    print(f"mcap-check: {len(topics)} channels, {sum(seen.values())} messages, "
          f"{sum(checked.values())} of them parsed into Foxglove's protobuf messages "
          f"({len(checked)} channels), {len(failures)} failures")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
