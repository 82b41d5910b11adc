"""ROS 2 bags written by rosbags: odometry and poses against the messages written, header stamps,
runs per bag or namespace, generic fields, `simcred compare` on two bags, 20 malformed bags."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore

from fuzz.test_cli_fuzz import run_isolated
from helpers import cli_compare_known_answer
from simcred.cli import run
from simcred.errors import OptionError, TraceSetError
from simcred.io import detect, read
from simcred.traces import RUN_INFO, TraceSet

STORE = get_typestore(Stores.ROS2_HUMBLE)
T = STORE.types
ODOM, POSE, FLOAT = "nav_msgs/msg/Odometry", "geometry_msgs/msg/PoseStamped", \
    "std_msgs/msg/Float64"


def header(t: float):
    sec = math.floor(t)
    return T["std_msgs/msg/Header"](stamp=T["builtin_interfaces/msg/Time"](
        sec=sec, nanosec=round((t - sec) * 1e9)), frame_id="map")


def pose(x: float, y: float, yaw: float):
    return T["geometry_msgs/msg/Pose"](
        position=T["geometry_msgs/msg/Point"](x=x, y=y, z=0.0),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                      w=math.cos(yaw / 2)))


def odometry(t: float, x: float, y: float, yaw: float, v: float):
    vec = T["geometry_msgs/msg/Vector3"]
    return T[ODOM](
        header=header(t), child_frame_id="base_link",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose(x, y, yaw),
                                                       covariance=np.zeros(36)),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](linear=vec(x=v, y=0.0, z=0.0),
                                               angular=vec(x=0.0, y=0.0, z=0.1)),
            covariance=np.zeros(36)))


def write_bag(path: Path, messages: dict[str, list], *, mcap: bool = False,
              received: float = 1000.0) -> Path:
    """A bag with ``messages[topic] = [msg, ...]``; receive times 10 ms apart from ``received``
    (the header stamps are the messages' own)."""
    plugin = StoragePlugin.MCAP if mcap else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        for topic, msgs in messages.items():
            connection = writer.add_connection(topic, msgs[0].__msgtype__, typestore=STORE)
            for k, msg in enumerate(msgs):
                stamp = int((received + 0.01 * k) * 1e9)
                writer.write(connection, stamp, STORE.serialize_cdr(msg, msg.__msgtype__))
    return path


def drive(t0: float, n: int = 5, v: float = 10.0, dt: float = 0.1) -> list:
    return [odometry(t0 + dt * k, v * dt * k, 1.0, 0.3, v) for k in range(n)]


def test_odometry_bag_is_one_run_with_header_stamps(tmp_path):
    bag = write_bag(tmp_path / "drive1", {"/odom": drive(1700000000.5)})
    assert detect(bag).name == "ros2"
    ts = read(bag)
    assert ts.run_ids == ("drive1",)
    assert ts.signals == ("x", "y", "z", "yaw", "vx", "vy", "yaw_rate")
    stamps = [header(1700000000.5 + 0.1 * k).stamp for k in range(5)]
    assert ts.time.tolist() == [s.sec + s.nanosec / 1e9 for s in stamps]
    assert ts.column("x").tolist() == [10.0 * 0.1 * k for k in range(5)]
    assert ts.column("yaw") == pytest.approx([0.3] * 5, abs=1e-12)
    assert ts.column("vx").tolist() == [10.0] * 5 and ts.column("yaw_rate").tolist() == [0.1] * 5
    assert ts.metadata["time"] == "header.stamp" and ts.units["yaw_rate"] == "rad/s"
    assert ts.metadata[RUN_INFO] == {"drive1": {"bag": "drive1", "topics": ["/odom"]}}


def test_mcap_storage_and_pose_topics_by_namespace(tmp_path):
    poses = {ns: [T[POSE](header=header(50.0 + 0.1 * k), pose=pose(k + i, -k, 0.0))
                  for k in range(4)] for i, ns in enumerate(("/car1/pose", "/car2/pose"))}
    bag = write_bag(tmp_path / "two", poses, mcap=True)
    ts = read(bag, runs="namespace")
    assert ts.run_ids == ("car1", "car2")
    assert ts.signals == ("x", "y", "z", "yaw")
    assert ts.run(1)["x"].tolist() == [1.0, 2.0, 3.0, 4.0]
    with pytest.raises(OptionError, match="runs must be one of bag, namespace"):
        read(bag, runs="topic")


def test_generic_field_path_and_receive_time(tmp_path):
    values = [T[FLOAT](data=float(k) ** 2) for k in range(4)]
    bag = write_bag(tmp_path / "f", {"/speed": values}, received=20.0)
    ts = read(bag, topics=["/speed"], fields=["data"])
    assert ts.signals == ("data",) and ts.column("data").tolist() == [0.0, 1.0, 4.0, 9.0]
    assert ts.time.tolist() == [20.0 + 0.01 * k for k in range(4)]  # no header: receive time
    assert ts.metadata["time"] == "receive"
    with pytest.raises(TraceSetError, match="no field 'value'"):
        read(bag, topics=["/speed"], fields=["value"])


def test_two_topics_with_the_same_stamps_are_leaf_prefixed(tmp_path):
    odom = drive(10.0)
    poses = [T[POSE](header=o.header, pose=o.pose.pose) for o in odom]
    ts = read(write_bag(tmp_path / "b", {"/odom": odom, "/pose": poses}))
    assert ts.signals[:2] == ("odom.x", "odom.y") and "pose.yaw" in ts.signals
    assert np.array_equal(ts.column("odom.x"), ts.column("pose.x"))


def test_a_bags_mcap_file_points_to_the_bag_directory(tmp_path):
    bag = write_bag(tmp_path / "m", {"/odom": drive(1.0)}, mcap=True)
    with pytest.raises(TraceSetError, match="m.mcap: the storage file of a ROS 2 bag; read the "
                                            "bag's directory"):
        read(bag / "m.mcap")
    assert read(bag).run_ids == ("m",)


def test_same_leaf_in_two_namespaces_is_refused_in_one_run(tmp_path):
    bag = write_bag(tmp_path / "b", {"/car1/odom": drive(1.0), "/car2/odom": drive(1.0)})
    with pytest.raises(TraceSetError, match="topics '/car1/odom' and '/car2/odom' would give "
                                            "the same signals 'odom.\\*'"):
        read(bag)
    assert read(bag, runs="namespace").run_ids == ("car1", "car2")


def test_a_directory_of_bags_is_a_run_per_bag(tmp_path):
    for k in (10, 2):
        write_bag(tmp_path / "bags" / f"run_{k}", {"/odom": drive(5.0, v=float(k))})
    ts = read(tmp_path / "bags")
    assert detect(tmp_path / "bags").name == "ros2"
    assert ts.run_ids == ("run_2", "run_10")
    assert ts.run(1)["vx"].tolist() == [10.0] * 5


# -- simcred compare on two bags: a known answer ---------------------------------------------------


def fleet(folder: Path, seed: int, phi: float) -> Path:
    """40 bags of 30 odometry messages each: an AR(1) speed (mcap storage)."""
    rng = np.random.default_rng(seed)
    for run_index in range(40):
        v = [rng.normal()]
        for _ in range(29):
            v.append(phi * v[-1] + rng.normal())
        msgs = [odometry(100.0 + 0.1 * k, 0.0, 0.0, 0.0, v[k]) for k in range(30)]
        write_bag(folder / f"bag_{run_index}", {"/odom": msgs}, mcap=True)
    return folder


@pytest.mark.parametrize("phi_b, same", [(0.8, True), (-0.8, False)])
def test_cli_compare_on_two_bag_sets(tmp_path, capsys, phi_b, same):
    a = fleet(tmp_path / "a", seed=1, phi=0.8)
    b = fleet(tmp_path / "b", seed=1, phi=phi_b)
    doc = cli_compare_known_answer(capsys, a, b, "vx", same)
    assert doc["units"] == ["m/s"]


def one_bag(path: Path, seed: int, phi: float) -> Path:
    """One bag of 40 vehicles (namespaces /car0 ... /car39), 30 odometry messages each."""
    rng = np.random.default_rng(seed)
    messages = {}
    for car in range(40):
        v = [rng.normal()]
        for _ in range(29):
            v.append(phi * v[-1] + rng.normal())
        messages[f"/car{car}/odom"] = [odometry(100.0 + 0.1 * k, 0.0, 0.0, 0.0, v[k])
                                       for k in range(30)]
    return write_bag(path, messages)


@pytest.mark.parametrize("phi_b, same", [(0.8, True), (-0.8, False)])
def test_cli_compare_on_two_single_bags_with_a_reader_option(tmp_path, capsys, phi_b, same):
    a = one_bag(tmp_path / "a", seed=1, phi=0.8)
    b = one_bag(tmp_path / "b", seed=1, phi=phi_b)
    cli_compare_known_answer(capsys, a, b, "vx", same, "--read", "runs=namespace")


def test_cli_compare_reader_option_errors_are_one_line(tmp_path, capsys):
    a = one_bag(tmp_path / "a", seed=1, phi=0.8)
    assert run(["compare", str(a), str(a), "-f", "vx", "--read", "runs"]) == 2
    assert "--read expects KEY=VALUE" in capsys.readouterr().err
    assert run(["compare", str(a), str(a), "-f", "vx", "--read", "runs=lanes"]) == 2
    assert "runs must be one of bag, namespace" in capsys.readouterr().err


# -- malformed bags: one line, exit 2 --------------------------------------------------------------


def _metadata(change):
    def build(bag: Path) -> list[str]:
        meta = bag / "metadata.yaml"
        meta.write_text(change(meta.read_text()))
        return ["compare", str(bag), str(bag), "-f", "vx"]
    return build


def _storage(change):
    def build(bag: Path) -> list[str]:
        db = next(bag.glob("*.db3"))
        db.write_bytes(change(db.read_bytes()))
        return ["compare", str(bag), str(bag), "-f", "vx"]
    return build


def _new(messages, *options):
    def build(bag: Path) -> list[str]:
        shutil.rmtree(bag)
        write_bag(bag, messages)
        return ["convert", str(bag), str(bag.parent / "out.parquet"), *options]
    return build


def _unlink(pattern):
    def build(bag: Path) -> list[str]:
        for p in bag.glob(pattern):
            p.unlink()
        return ["compare", str(bag), str(bag), "-f", "vx"]
    return build


BACKWARDS = [odometry(1.0, 0, 0, 0, 1.0), odometry(1.0, 0, 0, 0, 1.0)]
MALFORMED = {
    "empty metadata": _metadata(lambda s: ""),
    "metadata not yaml": _metadata(lambda s: "{{{: ["),
    "metadata version 99": _metadata(lambda s: s.replace("version: 9", "version: 99", 1)),
    "metadata list": _metadata(lambda s: "- 1\n- 2\n"),
    "unknown storage": _metadata(lambda s: s.replace("sqlite3", "leveldb", 1)),
    "no storage file": _unlink("*.db3"),
    "storage truncated": _storage(lambda b: b[:100]),
    "storage random": _storage(lambda b: np.random.default_rng(1).bytes(len(b))),
    "storage zeroed": _storage(lambda b: bytes(len(b))),
    "storage text": _storage(lambda b: b"not a database\n" * 20),
    "no odometry topic": _new({"/speed": [T[FLOAT](data=1.0), T[FLOAT](data=2.0)]}),
    "unknown topic": _new({"/odom": drive(1.0)}, "--topics", "/nope"),
    "field missing": _new({"/odom": drive(1.0)}, "--fields", "pose.nope"),
    "field not numeric": _new({"/odom": drive(1.0)}, "--fields", "child_frame_id"),
    "field is a message": _new({"/odom": drive(1.0)}, "--fields", "pose.pose"),
    "one message": _new({"/odom": drive(1.0, n=1)}),
    "repeated stamp": _new({"/odom": BACKWARDS}),
    "nan position": _new({"/odom": [odometry(1.0, float("nan"), 0, 0, 1.0)] + drive(2.0)}),
    "stamps differ": _new({"/odom": drive(1.0), "/pose": [T[POSE](header=header(7.0 + k),
                                                                  pose=pose(0, 0, 0))
                                                          for k in range(5)]}),
    "bad runs option": _new({"/odom": drive(1.0)}, "--runs", "topic"),
}


@pytest.mark.parametrize("name", list(MALFORMED))
def test_malformed_bag_is_one_line_exit_2(tmp_path, name):
    bag = write_bag(tmp_path / "corrupt_b", {"/odom": drive(1.0)})
    argv = MALFORMED[name](bag)
    code, out, err, elapsed = run_isolated(argv, 10)
    assert code is not None, "hang"
    lines = [line for line in err.splitlines() if line.strip()]
    assert code == 2, (code, err[-400:])
    assert len(lines) == 1 and lines[0].startswith("error:"), err[-400:]
    assert "Traceback" not in err + out
    if "--runs" not in argv:
        assert "corrupt_b" in lines[0], lines[0]


def test_twenty_malformed_cases():
    assert len(MALFORMED) == 20


def test_convert_a_bag_by_namespace_to_parquet(tmp_path, capsys):
    odoms = {f"/car{i}/odom": drive(3.0, v=float(i)) for i in (1, 2)}
    bag = write_bag(tmp_path / "bag", odoms)
    assert run(["--quiet", "convert", str(bag), str(tmp_path / "cars.parquet"), "--runs",
                "namespace"]) == 0
    back = TraceSet.read(tmp_path / "cars.parquet")
    assert back.run_ids == ("car1", "car2") and back.run(1)["vx"].tolist() == [2.0] * 5
    assert back.metadata["converted_from"]["format"] == "ros2"
    assert back.metadata[RUN_INFO]["car2"]["topics"] == ["/car2/odom"]
