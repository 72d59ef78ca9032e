"""ROS bags written as a robot logs them, for the reader and navigate tests."""
import numpy as np

FLU = np.array([[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])    # FLU components from RFU


def write_bag(path, imu, fx, ros1=False):
    """Write ``imu`` (RFU increments) as sensor_msgs/Imu rates in ROS axes (x forward, y left,
    z up), ``fx`` as NavSatFix (ENU covariance) and TwistWithCovarianceStamped (ENU
    velocity) messages, in a ROS 2 bag folder or (``ros1``) a ROS 1 ``.bag``."""
    from rosbags.typesys import Stores, get_typestore
    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    Imu, NavSatFix, Status = (ts.types[k] for k in ("sensor_msgs/msg/Imu", "sensor_msgs/msg/NavSatFix",
                                                     "sensor_msgs/msg/NavSatStatus"))
    Header, Time, V3, Q = (ts.types[k] for k in ("std_msgs/msg/Header", "builtin_interfaces/msg/Time",
                                                  "geometry_msgs/msg/Vector3", "geometry_msgs/msg/Quaternion"))
    TwC, TwCS, Tw = (ts.types[k] for k in ("geometry_msgs/msg/TwistWithCovariance",
                                            "geometry_msgs/msg/TwistWithCovarianceStamped",
                                            "geometry_msgs/msg/Twist"))

    def header(t, fid):
        sec = int(np.floor(t))
        stamp = Time(sec=sec, nanosec=int(round((t - sec) * 1e9)))
        return Header(seq=0, stamp=stamp, frame_id=fid) if ros1 else Header(stamp=stamp, frame_id=fid)

    if ros1:
        from rosbags.rosbag1 import Writer
        w = Writer(path)
        ser = ts.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer
        w = Writer(path, version=8)
        ser = ts.serialize_cdr
    z9 = np.zeros(9)
    with w:
        ci = w.add_connection("/imu/data", Imu.__msgtype__, typestore=ts)
        cf = w.add_connection("/gnss/fix", NavSatFix.__msgtype__, typestore=ts)
        cv = w.add_connection("/gnss/vel", TwCS.__msgtype__, typestore=ts)
        wb, fb = imu.dtheta @ FLU.T / imu.dt, imu.dv @ FLU.T / imu.dt
        for k, t in enumerate(imu.t):
            m = Imu(header=header(t, "imu_link"), orientation=Q(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=z9, angular_velocity=V3(x=wb[k, 0], y=wb[k, 1], z=wb[k, 2]),
                    angular_velocity_covariance=z9,
                    linear_acceleration=V3(x=fb[k, 0], y=fb[k, 1], z=fb[k, 2]), linear_acceleration_covariance=z9)
            w.write(ci, int(t * 1e9), ser(m, Imu.__msgtype__))
        for k, t in enumerate(fx.t):
            cov = np.diag([fx.sigma[k, 1] ** 2, fx.sigma[k, 0] ** 2, fx.sigma[k, 2] ** 2]).ravel()
            st = Status(status=0, service=1)
            m = NavSatFix(header=header(t, "gps"), status=st, latitude=np.degrees(fx.lat[k]),
                          longitude=np.degrees(fx.lon[k]), altitude=fx.h[k], position_covariance=cov,
                          position_covariance_type=2)
            w.write(cf, int(t * 1e9), ser(m, NavSatFix.__msgtype__))
            c6 = np.zeros(36)
            c6[[0, 7, 14]] = fx.sigma_vel[k] ** 2
            tw = TwCS(header=header(t, "gps"), twist=TwC(twist=Tw(linear=V3(x=fx.vel[k, 0], y=fx.vel[k, 1],
                                                                           z=fx.vel[k, 2]),
                                                              angular=V3(x=0.0, y=0.0, z=0.0)), covariance=c6))
            w.write(cv, int(t * 1e9), ser(tw, TwCS.__msgtype__))
