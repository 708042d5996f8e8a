"""MCAP that the ecosystem reads: chunked zstd files with indexes, Foxglove-typed view channels
(checked against Foxglove's own schema definitions), old JSON-only files, ROS 2 Bool bags."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import polars as pl
import pytest
from mcap.reader import make_reader
from mcap.writer import CompressionType, Writer

from onebit.core.errors import InputError
from onebit.core.site import load_site
from onebit.readers.mcap_io import (
    CHANNELS,
    TopicMapping,
    csv_folder_to_mcap,
    load_topic_map,
    mcap_to_csv_folder,
    read_mcap,
    tracks_for_views,
    write_mcap,
)
from onebit.readers.mcap_views import MARKER_POINTS, VIEW_TOPICS, message_classes

SITE = """name = "room"
units = "m"
[boundary]
polygon = [[0, 0], [6, 0], [6, 4], [0, 4]]
[[beams]]
id = "b1"
segment = [[3, 0], [3, 4]]
[[motion_sensors]]
id = "m1"
position = [1, 1]
range = 1.5
[[motion_sensors]]
id = "m2"
position = [5, 3]
range = 1.5
"""

MOTION = "t,sensor,value\n0.5,m1,1\n1.5,m1,0\n2.0,m2,on\n3.25,m2,off\n4.0,m1,1\n"
TRUTH = "t,target,x,y\n0.0,p1,1.0,1.0\n1.0,p1,2.0,1.5\n2.0,p1,4.5,2.5\n"
CROSSINGS = "t,beam,direction\n1.7,b1,1\n"


def _dataset(tmp: Path) -> Path:
    tmp.mkdir(parents=True, exist_ok=True)
    (tmp / "site.toml").write_text(SITE)
    (tmp / "motion.csv").write_text(MOTION)
    (tmp / "truth.csv").write_text(TRUTH)
    (tmp / "crossings.csv").write_text(CROSSINGS)
    return tmp


def _messages(path: Path) -> dict[str, list]:
    """Topic -> [(schema name, schema encoding, message encoding, log_time, data)]."""
    out: dict[str, list] = {}
    with open(path, "rb") as fh:
        for schema, channel, message in make_reader(fh).iter_messages():
            out.setdefault(channel.topic, []).append(
                (
                    schema.name if schema else "",
                    schema.encoding if schema else "",
                    channel.message_encoding,
                    message.log_time,
                    message.data,
                )
            )
    return out


def test_written_files_are_chunked_zstd_with_indexes(tmp_path):
    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(_dataset(tmp_path / "d"), out)
    with open(out, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.chunk_indexes
    assert {ci.compression for ci in summary.chunk_indexes} == {"zstd"}
    assert all(ci.message_index_offsets for ci in summary.chunk_indexes)  # message indexes per chunk
    assert all(ci.compressed_size < ci.uncompressed_size for ci in summary.chunk_indexes)
    n = sum(len(v) for v in _messages(out).values())
    assert summary.statistics.message_count == n
    topics = {c.topic for c in summary.channels.values()}
    assert {"/motion", "/truth", "/crossings"} <= topics
    assert {
        "/foxglove/site",
        "/foxglove/sensors",
        "/foxglove/truth",
        "/points/site",
        "/points/sensors",
        "/points/truth",
        "/events",
    } <= topics


def test_view_schemas_are_foxgloves_own_and_messages_decode(tmp_path):
    from google.protobuf.descriptor_pb2 import FileDescriptorSet
    from mcap_protobuf.schema import build_file_descriptor_set

    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(_dataset(tmp_path / "d"), out)
    msgs = _messages(out)
    classes = message_classes()
    for topic, type_name in VIEW_TOPICS.items():
        if topic not in msgs:
            assert topic in ("/foxglove/tracks", "/points/tracks"), topic
            continue
        names = {m[0] for m in msgs[topic]}
        assert names == {type_name}, topic
        assert {m[1] for m in msgs[topic]} == {"protobuf"} and {m[2] for m in msgs[topic]} == {"protobuf"}
    # the schema data is the FileDescriptorSet of Foxglove's published definitions
    with open(out, "rb") as fh:
        summary = make_reader(fh).get_summary()
    for schema in summary.schemas.values():
        if schema.encoding != "protobuf":
            continue
        ours = FileDescriptorSet.FromString(schema.data)
        theirs = build_file_descriptor_set(classes[schema.name])
        assert ours == theirs, schema.name
    # every message decodes with the Foxglove class; contents follow the logs
    log = [classes["foxglove.Log"].FromString(m[4]) for m in msgs["/events"]]
    assert [(x.name, x.message) for x in log] == [
        ("motion", "m1 1"),
        ("motion", "m1 0"),
        ("crossings", "b1 crossed 1"),
        ("motion", "m2 on"),
        ("motion", "m2 off"),
        ("motion", "m1 1"),
    ]
    assert [m[3] for m in msgs["/events"]] == [5 * 10**8, 15 * 10**8, 17 * 10**8, 2 * 10**9, 3_250_000_000, 4 * 10**9]
    clouds = [classes["foxglove.PointCloud"].FromString(m[4]) for m in msgs["/points/sensors"]]
    n = MARKER_POINTS  # each sensor is a ring of points
    assert len(clouds) == 5 and all(len(c.data) == 2 * n * c.point_stride for c in clouds)
    # the colour bytes of m1 (its ring's points) follow its toggles: on, off, off, off, on
    on = [c.data[12:16] for c in clouds]
    assert all(c.data[12:16] == c.data[(n - 1) * 16 + 12 : (n - 1) * 16 + 16] for c in clouds)
    assert on[0] == on[4] and on[1] == on[2] == on[3] and on[0] != on[1]
    truth = [classes["foxglove.SceneUpdate"].FromString(m[4]) for m in msgs["/foxglove/truth"]]
    assert [(u.entities[0].id, u.entities[0].spheres[0].pose.position.x) for u in truth] == [
        ("truth/p1", 1.0),
        ("truth/p1", 2.0),
        ("truth/p1", 4.5),
    ]
    site = classes["foxglove.SceneUpdate"].FromString(msgs["/foxglove/site"][0][4])
    ids = {e.id for e in site.entities}
    assert {"site/boundary", "site/beams/b1", "site/sensors/m1", "site/sensors/m2"} <= ids


def _fields(fds) -> dict[str, list]:
    """Every message of a FileDescriptorSet: full name -> (field name, number, type, label)."""
    return {
        f"{f.package}.{m.name}": sorted((x.name, x.number, x.type, x.label) for x in m.field)
        for f in fds.file
        for m in f.message_type
    }


def test_view_schemas_match_the_foxglove_sdk(tmp_path):
    """The schemas written are the Foxglove SDK's (``foxglove-sdk``, its ``foxglove.messages``):
    the same messages with the same fields, and bytes one side encodes the other decodes."""
    from google.protobuf.descriptor_pb2 import FileDescriptorSet

    messages = pytest.importorskip("foxglove.messages", reason="foxglove-sdk (the test extra) not installed")
    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(_dataset(tmp_path / "d"), out)
    with open(out, "rb") as fh:
        schemas = {s.name: s for s in make_reader(fh).get_summary().schemas.values() if s.encoding == "protobuf"}
    assert set(schemas) == {"foxglove.SceneUpdate", "foxglove.PointCloud", "foxglove.Log"}
    for name, schema in schemas.items():
        sdk = getattr(messages, name.split(".")[1]).get_schema()
        assert (sdk.name, sdk.encoding) == (name, "protobuf")
        ours, theirs = (
            _fields(FileDescriptorSet.FromString(schema.data)),
            _fields(FileDescriptorSet.FromString(sdk.data)),
        )
        assert ours == theirs and name in ours, name
    classes = message_classes()
    log = classes["foxglove.Log"].FromString(
        messages.Log(message="m1 on", name="motion", level=messages.LogLevel.Info).encode()
    )
    assert (log.message, log.name) == ("m1 on", "motion")


def test_round_trip_with_views_is_exact_and_views_are_skipped(tmp_path):
    src = _dataset(tmp_path / "d")
    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(src, out)
    got = read_mcap(out)
    assert got.rejects.height == 0 and not got.truncated
    assert set(got.views) >= {"/events", "/points/sensors", "/foxglove/site"} and got.views["/events"] == 6
    back = mcap_to_csv_folder(out, tmp_path / "back")
    assert back.rejects.height == 0
    for stem in ("motion", "truth", "crossings"):
        a = pl.read_csv(src / f"{stem}.csv", infer_schema=False)
        b = pl.read_csv(tmp_path / "back" / f"{stem}.csv", infer_schema=False)
        assert a.equals(b), stem


def test_without_views_and_with_tracks(tmp_path):
    src = _dataset(tmp_path / "d")
    bare = tmp_path / "bare.mcap"
    csv_folder_to_mcap(src, bare, views=False)
    assert set(_messages(bare)) == {"/motion", "/truth", "/crossings"}
    tracks = pl.DataFrame(
        {"tracker": ["intruder"] * 2, "track": ["intruder"] * 2, "t": [1.0, 3.0], "x": [1.5, None], "y": [1.0, None]}
    )
    rec = tmp_path / "tracks.mcap"
    csv_folder_to_mcap(src, rec, tracks=tracks_for_views(tracks, offset_s=0.5))
    msgs = _messages(rec)
    assert [m[3] for m in msgs["/foxglove/tracks"]] == [15 * 10**8]  # the null position is not drawn
    up = message_classes()["foxglove.SceneUpdate"].FromString(msgs["/foxglove/tracks"][0][4])
    assert up.entities[0].id == "tracks/intruder/intruder"


def test_old_json_only_unchunked_files_still_read(tmp_path):
    """Files of the earlier writer (unchunked, uncompressed, JSON only) read as before."""
    old = tmp_path / "old.mcap"
    with open(old, "wb") as fh:
        w = Writer(fh, compression=CompressionType.NONE, use_chunking=False)
        w.start(profile="", library="onebit")
        sid = w.register_schema(name="onebit.motion", encoding="jsonschema", data=b"{}")
        ch = w.register_channel(topic="/motion", message_encoding="json", schema_id=sid)
        for i, (t, s, v) in enumerate([(0.5, "m1", 1), (1.5, "m1", 0)]):
            w.add_message(
                ch,
                log_time=int(t * 1e9),
                publish_time=int(t * 1e9),
                sequence=i,
                data=f'{{"t": {t}, "sensor": "{s}", "value": {v}}}'.encode(),
            )
        w.finish()
    new = tmp_path / "new.mcap"
    write_mcap(
        new,
        {"/motion": pl.DataFrame({"t": [0.5, 1.5], "sensor": ["m1", "m1"], "value": [1, 0]})},
        site=load_site(_dataset(tmp_path / "d") / "site.toml"),
    )
    a, b = read_mcap(old), read_mcap(new)
    assert a.rejects.height == 0 and b.rejects.height == 0
    assert a.channels["/motion"].drop("raw").equals(b.channels["/motion"].drop("raw"))


# --------------------------------------------------------------------------- ROS 2 bags


def _ros2_bag(path: Path) -> None:
    from mcap_ros2.writer import Writer as Ros2Writer

    with open(path, "wb") as fh:
        w = Ros2Writer(fh)
        boolean = w.register_msgdef("std_msgs/msg/Bool", "bool data")
        text = w.register_msgdef("std_msgs/msg/String", "string data")
        for i, (topic, value) in enumerate(
            [("/hall/pir_a", True), ("/hall/pir_b", True), ("/hall/pir_a", False), ("/hall/pir_b", False)]
        ):
            ns = 1_700_000_000_000_000_000 + i * 500_000_000
            w.write_message(topic, boolean, {"data": value}, log_time=ns, publish_time=ns)
        w.write_message(
            "/chatter",
            text,
            {"data": "hello"},
            log_time=1_700_000_002_000_000_000,
            publish_time=1_700_000_002_000_000_000,
        )
        w.write_message(
            "/chatter",
            text,
            {"data": "again"},
            log_time=1_700_000_002_500_000_000,
            publish_time=1_700_000_002_500_000_000,
        )
        w.write_message(
            "/hall/pir_c",
            text,
            {"data": "not a bool"},
            log_time=1_700_000_003_000_000_000,
            publish_time=1_700_000_003_000_000_000,
        )
        w.finish()


def test_ros2_bool_topics_become_toggle_rows(tmp_path):
    bag = tmp_path / "bag.mcap"
    _ros2_bag(bag)
    topics = {
        "/hall/pir_a": TopicMapping(sensor="m1", kind="motion"),
        "/hall/pir_b": TopicMapping(sensor="p1", kind="proximity"),
        "/hall/pir_c": TopicMapping(sensor="m2", kind="motion"),
    }
    got = read_mcap(bag, topic_map=topics)
    motion = got.channels["/motion"]
    assert motion.select("t", "sensor", "value").rows() == [
        ("1700000000.000000000", "m1", "1"),
        ("1700000001.000000000", "m1", "0"),
    ]
    assert motion["raw"].to_list() == ["/hall/pir_a: data=True", "/hall/pir_a: data=False"]
    assert got.channels["/proximity"].select("sensor", "value").rows() == [("p1", "1"), ("p1", "0")]
    rej = got.rejects.sort("source")
    assert rej["source"].to_list() == ["bag.mcap:/chatter", "bag.mcap:/hall/pir_c"]
    assert (
        "2 message(s) in encoding 'cdr' (std_msgs/msg/String)" in rej["reason"][0]
        and "mcap_topics.toml" in rej["reason"][0]
    )
    assert "field 'data' is str, not a boolean" in rej["reason"][1] and rej["line"][1] == 1
    # without a map nothing is taken and every foreign channel is one counted reject
    bare = read_mcap(bag)
    assert bare.channels == {} and bare.rejects.height == 4


def test_ros2_bag_runs_through_the_pipeline(tmp_path):
    from onebit.pipeline.runner import run_pipeline

    d = tmp_path / "d"
    d.mkdir()
    (d / "site.toml").write_text(SITE)
    _ros2_bag(d / "recording.mcap")
    (d / "mcap_topics.toml").write_text('[topics."/hall/pir_a"]\nsensor = "m1"\nkind = "motion"\n')
    res = run_pipeline(d, tmp_path / "run", trackers=["intruder-naive"], progress=False)
    assert res.status["motion"].startswith("ok"), res.status
    motion = pl.read_parquet(tmp_path / "run" / "tables" / "motion.parquet")
    assert motion.select("t", "sensor", "on").rows() == [(0.0, "m1", True), (1.0, "m1", False)]


def test_topic_map_errors_name_the_file_and_topic(tmp_path):
    p = tmp_path / "mcap_topics.toml"
    p.write_text('[topics."/a"]\nsensor = "m1"\nkind = "beam"\n')
    with pytest.raises(InputError, match=r'mcap_topics.toml.*\[topics."/a"\].*kind'):
        load_topic_map(p)
    p.write_text('[topics."/a"]\nsensor = "m1"\n')
    with pytest.raises(InputError, match="needs sensor and kind"):
        load_topic_map(p)
    p.write_text('[topics."/motion"]\nsensor = "m1"\nkind = "motion"\n')
    with pytest.raises(InputError, match="onebit's own channels"):
        load_topic_map(p)
    p.write_text('[topics."/a"]\nsensor = "m1"\nkind = "motion"\nfield = "on"\n')
    assert load_topic_map(p) == {"/a": TopicMapping(sensor="m1", kind="motion", field="on")}
    assert set(CHANNELS).isdisjoint(VIEW_TOPICS)


def test_rerun_decodes_the_typed_channels(tmp_path):
    """Rerun's own MCAP importer (the ``rerun`` CLI of rerun-sdk) turns the views into
    Points3D and TextLog, and keeps the raw channels."""
    exe = Path(sys.executable).parent / "rerun"
    if not exe.exists():
        exe = shutil.which("rerun")
    if exe is None:
        pytest.skip("the rerun CLI of rerun-sdk is not installed")
    out = tmp_path / "rec.mcap"
    csv_folder_to_mcap(_dataset(tmp_path / "d"), out)
    rrd = tmp_path / "rec.rrd"
    subprocess.run(
        [str(exe), "mcap", "convert", str(out), "-o", str(rrd)], check=True, capture_output=True, timeout=120
    )
    printed = subprocess.run(
        [str(exe), "rrd", "print", str(rrd)], check=True, capture_output=True, text=True, timeout=120
    ).stdout
    lines = [ln for ln in printed.splitlines() if "data columns" in ln]

    def columns(topic: str) -> str:
        return " ".join(ln for ln in lines if f" - {topic} - " in ln)

    for topic in ("/points/site", "/points/sensors", "/points/truth"):
        assert "Points3D:positions" in columns(topic) and "Points3D:colors" in columns(topic), topic
    assert "TextLog:text" in columns("/events")
    assert "foxglove.SceneUpdate" in columns("/foxglove/site")
    assert columns("/motion")


def _unset_parts(msg, where: str = "") -> list[str]:
    """Every singular sub-message field (pose, position, orientation, timestamp, colour, ...) of
    ``msg`` and of its sub-messages that is not present, with its path."""
    out = []
    for f in msg.DESCRIPTOR.fields:
        if f.message_type is None:
            continue
        name = f"{where}.{f.name}" if where else f.name
        if f.is_repeated:
            for i, item in enumerate(getattr(msg, f.name)):
                out += _unset_parts(item, f"{name}[{i}]")
        elif not msg.HasField(f.name):
            out.append(name)
        else:
            out += _unset_parts(getattr(msg, f.name), name)
    return out


def _with_tracks(tmp: Path) -> Path:
    """The small dataset with a target and a track at the origin (all-zero positions) and a
    message at log time 0, converted with the track view."""
    src = _dataset(tmp / "d")
    (src / "truth.csv").write_text(TRUTH + "2.5,p2,0.0,0.0\n")
    tracks = pl.DataFrame(
        {
            "tracker": ["intruder"] * 3,
            "track": ["intruder"] * 3,
            "t": [0.0, 1.0, 3.0],
            "x": [0.0, 2.0, 4.0],
            "y": [0.0, 1.5, 2.0],
        }
    )
    out = tmp / "rec.mcap"
    csv_folder_to_mcap(src, out, tracks=tracks_for_views(tracks))
    return out


def test_every_typed_message_carries_its_poses_timestamps_and_frame(tmp_path):
    """No sub-message is left to proto3's defaults (absent on the wire): a PointCloud's pose has
    its position and orientation, every timestamp is present (also at 0 ns), every entity and
    point cloud names its frame."""
    out = _with_tracks(tmp_path)
    msgs = _messages(out)
    classes = message_classes()
    assert set(VIEW_TOPICS) <= set(msgs)
    for topic, type_name in VIEW_TOPICS.items():
        for _, _, _, log_time, data in msgs[topic]:
            m = classes[type_name].FromString(data)
            assert _unset_parts(m) == [], (topic, log_time)
            if type_name == "foxglove.PointCloud":
                assert m.frame_id == "site"
                assert (m.pose.orientation.w, m.pose.position.x) == (1.0, 0.0)
            if type_name == "foxglove.SceneUpdate":
                assert all(e.frame_id == "site" for e in m.entities)
            stamps = [m.timestamp] if type_name != "foxglove.SceneUpdate" else [e.timestamp for e in m.entities]
            assert stamps and all(s.seconds * 10**9 + s.nanos == log_time for s in stamps), (topic, log_time)
    assert min(m[3] for m in msgs["/points/tracks"]) == 0


def _rerun_cli() -> str:
    """The ``rerun`` CLI beside this interpreter (rerun-sdk) or on PATH, if it has the
    ``mcap convert`` and ``rrd verify`` subcommands; else the test is skipped."""
    exe = Path(sys.executable).parent / "rerun"
    path = str(exe) if exe.exists() else shutil.which("rerun")
    if path is None:
        pytest.skip("the rerun CLI of rerun-sdk is not installed")
    for group, sub in (("mcap", "convert"), ("rrd", "verify")):
        helptext = subprocess.run([path, group, "--help"], capture_output=True, text=True, timeout=60).stdout
        if sub not in helptext:
            pytest.skip(f"this rerun CLI has no `rerun {group} {sub}`")
    return path


@pytest.mark.parametrize("timeline", ["timestamp", "duration"])
def test_converted_recording_verifies(tmp_path, timeline):
    """``rerun mcap convert`` of a written MCAP gives a recording ``rerun rrd verify`` accepts:
    the small dataset with tracks at the origin, and a short pir14 demo."""
    from onebit.datasets.catalogue import get_scenario

    exe = _rerun_cli()
    demo = get_scenario("pir14").write(
        tmp_path / "pir14", seed=5, duration=20.0, agents=None, drop=0.0, camera=False, params={"refractory": 4}
    )
    csv_folder_to_mcap(demo, tmp_path / "pir14.mcap")
    for mcap in (_with_tracks(tmp_path), tmp_path / "pir14.mcap"):
        rrd = mcap.with_suffix(".rrd")
        subprocess.run(
            [exe, "mcap", "convert", str(mcap), "--timeline-type", timeline, "-o", str(rrd)],
            check=True,
            capture_output=True,
            timeout=120,
        )
        verify = subprocess.run([exe, "rrd", "verify", str(rrd)], capture_output=True, text=True, timeout=120)
        assert verify.returncode == 0, verify.stdout + verify.stderr
        assert "verified without error" in verify.stdout + verify.stderr
