/* The yardstick strapdown loop of benchmarks/speed.py in C: the same full ENU update as
 * the numba reference kernel (2-sample coning and sculling, Earth and transport rate,
 * normal gravity, position), statement for statement, so that a C compiler's build of it
 * says what a scalar loop of this arithmetic costs on the machine.
 *
 * benchmarks/speed.py compiles it (cc -O2 -shared -fPIC) when a C compiler is found and
 * calls `nav` through ctypes on the same arrays as the other kernels; `state` holds
 * q0..q3, vE, vN, vU, lat, lon, h on entry and on return. No -ffast-math: IEEE
 * arithmetic, as numba's. */
#include <math.h>

#define WIE 7.2921151467e-5
#define RE 6378137.0
#define E2 0.00669437999014

static inline void cross(double ax, double ay, double az, double bx, double by, double bz,
                         double *cx, double *cy, double *cz)
{
    *cx = ay * bz - az * by;
    *cy = az * bx - ax * bz;
    *cz = ax * by - ay * bx;
}

static inline void qmul(double a0, double a1, double a2, double a3,
                        double b0, double b1, double b2, double b3, double *q)
{
    q[0] = a0 * b0 - a1 * b1 - a2 * b2 - a3 * b3;
    q[1] = a0 * b1 + a1 * b0 + a2 * b3 - a3 * b2;
    q[2] = a0 * b2 - a1 * b3 + a2 * b0 + a3 * b1;
    q[3] = a0 * b3 + a1 * b2 - a2 * b1 + a3 * b0;
}

static inline void rv2q(double x, double y, double z, double *q)
{
    double n = sqrt(x * x + y * y + z * z);
    double s = n > 1e-12 ? sin(n / 2) / n : 0.5 - n * n / 48;
    q[0] = cos(n / 2);
    q[1] = x * s;
    q[2] = y * s;
    q[3] = z * s;
}

/* dth, dvl: n x 3 row-major increments [rad], [m/s]; dt [s]; state[10] in and out. */
void nav(const double *dth, const double *dvl, long n, double dt, double *state)
{
    double q0 = state[0], q1 = state[1], q2 = state[2], q3 = state[3];
    double ve = state[4], vn = state[5], vu = state[6];
    double lat = state[7], lon = state[8], h = state[9];
    double T = 2 * dt;
    for (long k = 0; k < n - 1; k += 2) {
        const double *a1 = dth + 3 * k, *a2 = dth + 3 * (k + 1);
        const double *b1 = dvl + 3 * k, *b2 = dvl + 3 * (k + 1);
        double cx, cy, cz;
        cross(a1[0], a1[1], a1[2], a2[0], a2[1], a2[2], &cx, &cy, &cz);
        double px = a1[0] + a2[0] + 2.0 / 3 * cx, py = a1[1] + a2[1] + 2.0 / 3 * cy,
               pz = a1[2] + a2[2] + 2.0 / 3 * cz;
        double ax = a1[0] + a2[0], ay = a1[1] + a2[1], az = a1[2] + a2[2];
        double bx = b1[0] + b2[0], by = b1[1] + b2[1], bz = b1[2] + b2[2];
        double r1x, r1y, r1z, s1x, s1y, s1z, s2x, s2y, s2z;
        cross(ax, ay, az, bx, by, bz, &r1x, &r1y, &r1z);
        cross(a1[0], a1[1], a1[2], b2[0], b2[1], b2[2], &s1x, &s1y, &s1z);
        cross(b1[0], b1[1], b1[2], a2[0], a2[1], a2[2], &s2x, &s2y, &s2z);
        double dx = bx + 0.5 * r1x + 2.0 / 3 * (s1x + s2x);
        double dy = by + 0.5 * r1y + 2.0 / 3 * (s1y + s2y);
        double dz = bz + 0.5 * r1z + 2.0 / 3 * (s1z + s2z);
        double sl = sin(lat), cl = cos(lat);
        double sq2 = 1 - E2 * sl * sl, sq = sqrt(sq2);
        double RN = RE * (1 - E2) / (sq2 * sq) + h, RE_ = RE / sq + h;
        double wiey = WIE * cl, wiez = WIE * sl;
        double wex = -vn / RN, wey = ve / RE_, wez = ve * sl / cl / RE_;
        double wx = wex, wy = wiey + wey, wz = wiez + wez;
        double g = 9.7803267714 * (1 + 0.00193185138639 * sl * sl) / sq - 3.086e-6 * h;
        double C00 = 1 - 2 * (q2 * q2 + q3 * q3), C01 = 2 * (q1 * q2 - q0 * q3), C02 = 2 * (q1 * q3 + q0 * q2);
        double C10 = 2 * (q1 * q2 + q0 * q3), C11 = 1 - 2 * (q1 * q1 + q3 * q3), C12 = 2 * (q2 * q3 - q0 * q1);
        double C20 = 2 * (q1 * q3 - q0 * q2), C21 = 2 * (q2 * q3 + q0 * q1), C22 = 1 - 2 * (q1 * q1 + q2 * q2);
        double nx = C00 * dx + C01 * dy + C02 * dz;
        double ny = C10 * dx + C11 * dy + C12 * dz;
        double nz = C20 * dx + C21 * dy + C22 * dz;
        double zx = wx * T, zy = wy * T, zz = wz * T;
        double rrx, rry, rrz, ccx, ccy, ccz;
        cross(zx, zy, zz, nx, ny, nz, &rrx, &rry, &rrz);
        cross(wex, 2 * wiey + wey, 2 * wiez + wez, ve, vn, vu, &ccx, &ccy, &ccz);
        double nve = ve + nx - 0.5 * rrx - ccx * T;
        double nvn = vn + ny - 0.5 * rry - ccy * T;
        double nvu = vu + nz - 0.5 * rrz + (-g - ccz) * T;
        lat += 0.5 * (vn + nvn) / RN * T;
        lon += 0.5 * (ve + nve) / (RE_ * cl) * T;
        h += 0.5 * (vu + nvu) * T;
        ve = nve;
        vn = nvn;
        vu = nvu;
        double b[4], e[4], t[4], q[4];
        rv2q(px, py, pz, b);
        rv2q(-zx, -zy, -zz, e);
        qmul(q0, q1, q2, q3, b[0], b[1], b[2], b[3], t);
        qmul(e[0], e[1], e[2], e[3], t[0], t[1], t[2], t[3], q);
        double nq = 1.0 / sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
        q0 = q[0] * nq;
        q1 = q[1] * nq;
        q2 = q[2] * nq;
        q3 = q[3] * nq;
    }
    state[0] = q0; state[1] = q1; state[2] = q2; state[3] = q3;
    state[4] = ve; state[5] = vn; state[6] = vu;
    state[7] = lat; state[8] = lon; state[9] = h;
}
