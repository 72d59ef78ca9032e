"""ROS 1 bags (``.bag``) and ROS 2 bags (a folder with ``metadata.yaml``, or its ``.db3`` /
``.mcap`` file) read through ``rosbags`` (pure Python; no ROS installation):

- ``sensor_msgs/Imu``: ``header.stamp``, ``angular_velocity`` (rad/s),
  ``linear_acceleration`` (m/s²) in the message's frame, which ROS (REP 103) makes
  x-forward, y-left, z-up: the rates become increments over the interval ending at each
  stamp;
- ``sensor_msgs/NavSatFix``: latitude, longitude (deg), altitude (m above the WGS-84
  ellipsoid), ``position_covariance`` (ENU, m²; its ``position_covariance_type`` 0 =
  unknown), ``status.status`` (−1: no fix, dropped);
- ``geometry_msgs/TwistWithCovarianceStamped`` (a GNSS receiver's velocity: linear x, y,
  z east, north, up, and its covariance), matched to the fixes by stamp.

The topic of each kind is found by its message type; where a bag holds several of a kind,
the one with most messages is used and the others named (``topic=`` picks one).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from sinslab.core.records import Fixes
from sinslab.data.frames import sensor_to_body
from sinslab.data.increments import ImuData, check_stamps, rates_to_increments, uniform_increments

__all__ = ["is_rosbag", "read_rosbag_imu", "read_rosbag_fixes", "IMU_TYPE", "FIX_TYPE", "TWIST_TYPE"]

IMU_TYPE = "sensor_msgs/msg/Imu"
FIX_TYPE = "sensor_msgs/msg/NavSatFix"
TWIST_TYPE = "geometry_msgs/msg/TwistWithCovarianceStamped"


def is_rosbag(path) -> bool:
    """A ROS 1 bag (``.bag``, ``#ROSBAG`` magic) or a ROS 2 bag (a folder with
    ``metadata.yaml``, or a ``.db3``/``.mcap`` file beside one)."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    if p.suffix.lower() in (".db3", ".mcap") and (p.parent / "metadata.yaml").is_file():
        return True
    try:
        with open(p, "rb") as fh:
            return fh.read(9) == b"#ROSBAG V"
    except OSError:
        return False


def _bag_path(path):
    p = Path(path)
    return p.parent if p.suffix.lower() in (".db3", ".mcap") and not p.is_dir() else p


def _messages(path, msgtype, topic=None, what="messages"):
    """``(topic, [(stamp [s], message)], other topics of the type)`` for one topic of
    ``msgtype``: ``topic`` if given, else the one with most messages."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore
    p = _bag_path(path)
    try:
        reader = AnyReader([p], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        reader.open()
    except Exception as e:  # noqa: BLE001 - rosbags raises its own kinds
        raise ValueError(f"{path}: cannot read as a ROS bag ({e})") from None
    try:
        conns = [c for c in reader.connections if c.msgtype == msgtype]
        topics = {}
        for c in conns:
            topics[c.topic] = topics.get(c.topic, 0) + c.msgcount
        if topic is not None:
            if topic not in topics:
                raise ValueError(f"{path}: no {msgtype.replace('/msg/', '/')} topic {topic!r} "
                                 f"(the bag has {', '.join(sorted(topics)) or 'none'})")
            chosen = topic
        elif not topics:
            have = sorted({f"{c.topic} ({c.msgtype.replace('/msg/', '/')})" for c in reader.connections})
            raise ValueError(f"{path}: no {msgtype.replace('/msg/', '/')} {what} in the bag "
                             f"(it has {', '.join(have) or 'no topics'})")
        else:
            chosen = max(topics, key=lambda k: (topics[k], k))
        out = []
        for c, tstamp, raw in reader.messages(connections=[c for c in conns if c.topic == chosen]):
            msg = reader.deserialize(raw, c.msgtype)
            st = msg.header.stamp
            t = st.sec + st.nanosec * 1e-9
            out.append((t if t > 0 else tstamp * 1e-9, msg))
    finally:
        reader.close()
    if not out:
        raise ValueError(f"{path}: topic {chosen!r} holds no messages")
    out.sort(key=lambda x: x[0])
    return chosen, out, sorted(k for k in topics if k != chosen)


def read_rosbag_imu(path, *, topic=None, frame="flu", mount=None, max_gap=1.0, allow_gaps=False) -> ImuData:
    """Read the ``sensor_msgs/Imu`` messages of a bag as increments (see the module notes).
    Axes x-forward, y-left, z-up (REP 103) unless ``frame``/``mount`` say otherwise."""
    chosen, msgs, others = _messages(path, IMU_TYPE, topic, "IMU messages")
    t = np.array([m[0] for m in msgs])
    w = np.array([[m[1].angular_velocity.x, m[1].angular_velocity.y, m[1].angular_velocity.z] for m in msgs])
    f = np.array([[m[1].linear_acceleration.x, m[1].linear_acceleration.y, m[1].linear_acceleration.z]
                  for m in msgs])
    lines = [f"{chosen} message {i + 1}" for i in range(t.size)]
    if t.size < 2:
        raise ValueError(f"{path}: topic {chosen!r} holds {t.size} IMU message; needs at least 2")
    check_stamps(t, path, lines)
    bad = ~np.isfinite(np.hstack([w, f]))
    if bad.any():
        raise ValueError(f"{path}: {lines[int(np.argwhere(bad)[0][0])]}: NaN/inf rate or acceleration")
    R = sensor_to_body(mount, frame)
    dth, dv = rates_to_increments(t, w @ R.T, f @ R.T, float(np.median(np.diff(t))))
    imu, gaps, jit = uniform_increments(t, dth, dv, path=path, lines=lines, max_gap=max_gap,
                                        allow_gaps=allow_gaps)
    meta = {"topic": chosen, "other_topics": others, "frame_id": msgs[0][1].header.frame_id}
    return ImuData(imu, gaps, str(path), "rosbag", t.size, jit, meta)


def _cov_sigma(cov, idx):
    c = np.asarray(cov, dtype=float)
    return np.sqrt(np.maximum(c[idx], 0.0))


def read_rosbag_fixes(path, *, topic=None, velocity_topic=None, sigma=None):
    """Fixes from the ``sensor_msgs/NavSatFix`` messages of a bag, with the velocities of a
    ``TwistWithCovarianceStamped`` topic when the bag has one (stamps matched within a
    quarter of the fix interval). σ from each message's covariance; where its type is 0
    (unknown) or it is zero, ``sigma`` (north, east, up, default 1, 1, 2 m) — the meta says
    which. Returns ``(Fixes, meta)``."""
    chosen, msgs, others = _messages(path, FIX_TYPE, topic, "NavSatFix messages")
    status = np.array([m[1].status.status for m in msgs])
    keep = status >= 0
    dropped = int((~keep).sum())
    msgs = [m for m, k in zip(msgs, keep) if k]
    if not msgs:
        raise ValueError(f"{path}: topic {chosen!r}: every NavSatFix says no fix (status -1)")
    t = np.array([m[0] for m in msgs])
    check_stamps(t, path, [f"{chosen} message {i + 1}" for i in range(t.size)])
    lat = np.radians([m[1].latitude for m in msgs])
    lon = np.radians([m[1].longitude for m in msgs])
    h = np.array([m[1].altitude for m in msgs], dtype=float)
    ctype = np.array([m[1].position_covariance_type for m in msgs])
    sig = np.array([_cov_sigma(m[1].position_covariance, [4, 0, 8]) for m in msgs])   # N, E, U
    default = np.array([1.0, 1.0, 2.0] if sigma is None else np.broadcast_to(sigma, 3), dtype=float)
    unknown = (ctype == 0) | np.any(~(sig > 0), axis=1)
    sig[unknown] = default
    meta = {"format": "rosbag", "topic": chosen, "other_topics": others, "no_fix_dropped": dropped,
            "sigma_source": (f"{chosen} position_covariance" if not unknown.any() else
                             f"{chosen} position_covariance; {int(unknown.sum())} of {t.size} messages "
                             f"without one: default {default[0]:g}, {default[1]:g}, {default[2]:g} m")}
    vel = sv = None
    try:
        vtopic, vmsgs, _ = _messages(path, TWIST_TYPE, velocity_topic, "velocity messages")
    except ValueError:
        if velocity_topic is not None:
            raise
        vmsgs = None
    if vmsgs:
        tv = np.array([m[0] for m in vmsgs])
        v = np.array([[m[1].twist.twist.linear.x, m[1].twist.twist.linear.y, m[1].twist.twist.linear.z]
                      for m in vmsgs])
        s = np.array([_cov_sigma(m[1].twist.covariance, [0, 7, 14]) for m in vmsgs])
        j = np.clip(np.searchsorted(tv, t), 1, max(tv.size - 1, 1))
        j = np.where(np.abs(tv[j - 1] - t) <= np.abs(tv[np.minimum(j, tv.size - 1)] - t), j - 1, j)
        j = np.minimum(j, tv.size - 1)
        tol = 0.25 * float(np.median(np.diff(t))) if t.size > 1 else 0.05
        ok = np.abs(tv[j] - t) <= tol
        if ok.all():
            vel = v[j]
            sv = np.where(s[j] > 0, s[j], 0.1)
            meta.update(velocity_topic=vtopic, velocity_frame="ENU")
        else:
            meta["velocity_unmatched"] = (vtopic, int((~ok).sum()))
    fx = Fixes(t, lat, lon, h, sig, vel, sv, status[keep].astype(int), str(path))
    return fx, meta
