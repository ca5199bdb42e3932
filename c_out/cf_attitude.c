/*
 * cf_attitude.c - the attitude filter's step (C99, libm only, no allocation)
 *
 * GENERATED FILE - DO NOT EDIT.  Regenerate it from the filter instead:
 *     cfdesign.codegen.attitude.write_attitude_c(AttitudeFilter(rate_hz, ...), directory)
 *
 * generator : cfdesign 0.1.0 (cfdesign.codegen.attitude, C99, double)
 * filter    : cfdesign.nav.AttitudeFilter at 100.0 Hz, 9D (magnetometer)
 * frames    : body (sensor) frame relative to ENU; quaternions [w, x, y, z] body -> ENU
 * parameters:
 *     gyro_noise_density=0.0002, gyro_bias_density=1e-05, accel_noise_density=0.003,
 *     tilt_drift_density=0.0008, velocity_noise_density=0.032, tilt_noise_density=0.05,
 *     heading_noise_density=0.008, declination_rad=0.0, gyro_bias_std0=0.0175,
 *     heading_bias_std0=0.0005, rest_time_s=1.5, rest_filter_s=0.5, rest_sigma=3.0,
 *     mag_tolerance_rad=0.14, mag_filter_s=0.2, mag_reference_s=20.0, mag_new_field_s=40.0,
 *     mag_new_field_rotation_rad=1.5707963267948966, max_speed_mps=4.0, max_accel_time_s=30.0,
 *     max_reach_m=1.0, gyro_range_rps=100.0, accel_range_mps2=1000.0, rest_detection=True,
 *     mag_rejection=True, accel_rejection=True, motion_bias=True, inertial_tilt=True
 */
#include <math.h>
#include <stddef.h>

#include "cf_attitude.h"

/*
 * The designed tables' numbers (hexadecimal literals: the Python floats exactly) and the
 * derived constants; see cfdesign.nav.attitude_filter (AttitudeDesign, _coefficients).
 */
static const double T = 0x1.47ae147ae147bp-7;
static const double REST_ALPHA = 0x1.446cc8a427492p-6;
static const double REST_GYRO_TH2 = 0x1.c4fc1df3300dep-14;
static const double REST_ACCEL_TH2 = 0x1.8e219652bd3c3p-6;
static const double REST_BIAS_TH2 = 0x1.694467381d7ddp-9;
static const double REST_TIME = 0x1.8000000000000p+0;
static const double MAG_ALPHA = 0x1.8f874f58d95a0p-5;
static const double MAG_REF_ALPHA = 0x1.061416eeb48bcp-11;
static const double NORTH = 0x1.921fb54442d18p+0;
static const double SPEED2 = 0x1.0000000000000p+4;
static const double MAX_ACCEL_TIME = 0x1.e000000000000p+4;
static const double ACCEL_HOLD = 0x1.0000000000000p-2;
static const double TILT_ALPHA = 0x1.447f27271f551p-8;
static const double GYRO_RANGE2 = 0x1.3880000000000p+13;
static const double ACCEL_RANGE2 = 0x1.e848000000000p+19;
static const double MAG_TOL = 0x1.1eb851eb851ecp-3;
static const double MAG_NEW_TIME = 0x1.4000000000000p+5;
static const double MAG_NEW_TURN = 0x1.921fb54442d18p+0;
static const double HOLD_VAR = 0x1.b7cdfd9d7bdbcp-32;
static const double GRAVITY = 0x1.39d013a92a305p+3;
static const double PI = 0x1.921fb54442d18p+1;
static const double TWO_PI = 0x1.921fb54442d18p+2;
/* velocity channel gains {k1, k2}: motion, rest, then the acceleration-disturbance levels */
#define NVEL 7
static const double VELOCITY[NVEL][2] = {
    {0x1.cd5edcfdca6eap-8, 0x1.4036102fe216fp-9},
    {0x1.3db4185edc989p-1, 0x1.9c686677a8b25p-2},
    {0x1.cb20f0f3fda87p-9, 0x1.40c7ef9014754p-11},
    {0x1.cac340ef45e78p-10, 0x1.411020d96527ep-13},
    {0x1.cac563161199ap-11, 0x1.41342488a0732p-15},
    {0x1.cad2c2238bf48p-12, 0x1.414624813a2d5p-17},
    {0x1.cadc86bae1fbfp-13, 0x1.414f2471f6c55p-19}
};
/* tilt, heading and zero-rotation channels: {q00, q01, q11, r, kalman, k1, k2} */
static const double TILT[7] = {0x1.b7ce000460130p-32, 0x1.6849b86a12b9cp-48, 0x1.19799812dea12p-40, 0x1.0000000000000p-2, 0x1.0000000000000p+0, 0x1.abb171b0be507p-13, 0x1.0c687813f0d8bp-19};
static const double HEADING[7] = {0x1.b7ce000460130p-32, 0x1.6849b86a12b9cp-48, 0x1.19799812dea12p-40, 0x1.a36e2eb1c432dp-8, 0x1.0000000000000p+0, 0x1.250105ee5ec89p-11, 0x1.a3502cb26da95p-17};
static const double REST[7] = {0x1.b7ce000460130p-32, 0x1.6849b86a12b9cp-48, 0x1.19799812dea12p-40, 0x1.b7cdfd9d7bdbcp-32, 0x1.0000000000000p+0, 0x1.3c87f880eb52dp-1, 0x1.fa2abb34c0499p-6};
static const double PRIOR[9] = {0x1.b7cdfd9d7bdbcp-32, 0x0.0p+0, 0x1.41205bc01a36fp-12, 0x1.0000000000000p-2, 0x0.0p+0, 0x1.41205bc01a36fp-12, 0x1.a51a6625307d3p+1, 0x0.0p+0, 0x1.0c6f7a0b5ed8dp-22};       /* r00 r01 r11, t00 t01 t11, h00 h01 h11 */
static const double INITIAL[5] = {0x0.0p+0, 0x0.0p+0, 0x0.0p+0, 0x0.0p+0, 0x0.0p+0};    /* started, qw, qx, qy, qz */
/* mechanisms: rest detection, magnetic check, acceleration levels, motion bias, inertial tilt */
static const int USE_REST = 1;
static const int USE_MAG_CHECK = 1;
static const int USE_LEVELS = 1;
static const int USE_MOTION_BIAS = 1;
static const int INERTIAL = 1;

/* a wrapped to (-pi, pi] (cfdesign.linear.wrap_scalar; in-range angles unchanged) */
static double wrap_angle(double a)
{
    double r;

    if (a > -PI && a <= PI)
        return a;
    r = a - TWO_PI * ceil((a - PI) / TWO_PI);
    if (r > PI)
        r -= TWO_PI;
    else if (r <= -PI)
        r += TWO_PI;
    return r;
}

void cf_attitude_init(cf_attitude_state *s)
{
    double *v = (double *)s;
    size_t i;

    for (i = 0; i < sizeof(*s) / sizeof(double); ++i)
        v[i] = 0.0;
    s->qw = 1.0;
    if (INITIAL[0] != 0.0) {
        s->qw = INITIAL[1];
        s->qx = INITIAL[2];
        s->qy = INITIAL[3];
        s->qz = INITIAL[4];
        s->started = 1.0;
    }
    s->r00 = PRIOR[0];
    s->r01 = PRIOR[1];
    s->r11 = PRIOR[2];
    s->t00 = PRIOR[3];
    s->t01 = PRIOR[4];
    s->t11 = PRIOR[5];
    s->h00 = PRIOR[6];
    s->h01 = PRIOR[7];
    s->h11 = PRIOR[8];
}

/*
 * The operations of cfdesign.nav.attitude_filter._step in the same order (a tuple
 * assignment there is a set of temporaries here).
 */
void cf_attitude_step(cf_attitude_state *s, const double gyr[3], const double acc[3], const double *mag,
                    double q_out[4])
{
    double gx = gyr[0], gy = gyr[1], gz = gyr[2];
    const double ax = acc[0], ay = acc[1], az = acc[2];
    double mx = 0.0, my = 0.0, mz = 0.0, m2 = 0.0, f2;
    double qw = s->qw, qx = s->qx, qy = s->qy, qz = s->qz, bx = s->bx, by = s->by, bz = s->bz;
    double ux = 0.0, uy = 0.0, uz = 0.0, ang = 0.0, sc, cw, dx, dy, dz, n, a0, a1, a2, a3;
    double r0, r1, r2, r3, r4, r5, r6, r7, r8, cx = 0.0, cy = 0.0, cz = 0.0, ang_c;
    int acc_ok, mag_ok = 0, first, still = 0, was_rest, rest;

    /* readings: an impossible or non-finite one is missing (NaN fails every comparison) */
    if (gx * gx + gy * gy + gz * gz <= GYRO_RANGE2) {
        s->lgx = gx;
        s->lgy = gy;
        s->lgz = gz;
    } else {
        s->missing_gyr += 1.0;
        gx = s->lgx;
        gy = s->lgy;
        gz = s->lgz;
    }
    f2 = ax * ax + ay * ay + az * az;
    acc_ok = 0.0 < f2 && f2 <= ACCEL_RANGE2;
    if (!acc_ok)
        s->missing_acc += 1.0;
    if (CF_ATTITUDE_NINE_D) {
        if (mag != NULL) {
            mx = mag[0];
            my = mag[1];
            mz = mag[2];
            m2 = mx * mx + my * my + mz * mz;
            mag_ok = 0.0 < m2 && m2 < HUGE_VAL;
        }
        if (!mag_ok)
            s->missing_mag += 1.0;
    }

    if (s->started < 2.0) {
        /* the first step: the attitude is the initial one (given, or the tilt of this specific force) */
        if (s->started == 0.0) {
            double fn, uw;

            if (!acc_ok) {
                q_out[0] = s->qw < 0.0 ? -s->qw : s->qw;
                q_out[1] = s->qw < 0.0 ? -s->qx : s->qx;
                q_out[2] = s->qw < 0.0 ? -s->qy : s->qy;
                q_out[3] = s->qw < 0.0 ? -s->qz : s->qz;
                return;
            }
            fn = sqrt(f2);
            uw = 1.0 + az / fn;
            if (uw > 1e-9) {
                qw = uw;
                qx = ay / fn;
                qy = -ax / fn;
                qz = 0.0;
            } else {
                qw = 0.0;
                qx = 1.0;
                qy = 0.0;
                qz = 0.0;
            }
            n = sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
            qw = qw / n;
            qx = qx / n;
            qy = qy / n;
            qz = qz / n;
            s->tilt_n = 1.0;
        }
        s->gx = gx;
        s->gy = gy;
        s->gz = gz;
        if (acc_ok) {
            s->fx = ax;
            s->fy = ay;
            s->fz = az;
        }
        s->started = 2.0;
        first = 1;
    } else {
        first = 0;
    }

    /* rest detection (body frame) */
    s->gx += REST_ALPHA * (gx - s->gx);
    s->gy += REST_ALPHA * (gy - s->gy);
    s->gz += REST_ALPHA * (gz - s->gz);
    s->gyro_dev += REST_ALPHA * ((gx - s->gx) * (gx - s->gx) + (gy - s->gy) * (gy - s->gy)
                                 + (gz - s->gz) * (gz - s->gz) - s->gyro_dev);
    if (acc_ok) {
        double db;

        s->fx += REST_ALPHA * (ax - s->fx);
        s->fy += REST_ALPHA * (ay - s->fy);
        s->fz += REST_ALPHA * (az - s->fz);
        s->accel_dev += REST_ALPHA * ((ax - s->fx) * (ax - s->fx) + (ay - s->fy) * (ay - s->fy)
                                      + (az - s->fz) * (az - s->fz) - s->accel_dev);
        db = (s->gx - bx) * (s->gx - bx) + (s->gy - by) * (s->gy - by) + (s->gz - bz) * (s->gz - bz);
        still = USE_REST && s->gyro_dev < REST_GYRO_TH2 && s->accel_dev < REST_ACCEL_TH2 && db < REST_BIAS_TH2;
    }
    was_rest = s->rest_time >= REST_TIME;
    s->rest_time = still ? s->rest_time + T : 0.0;
    rest = s->rest_time >= REST_TIME;

    /* the gyro: q <- q (x) exp((w - b) T / 2) */
    if (!first) {
        ux = (gx - bx) * T;
        uy = (gy - by) * T;
        uz = (gz - bz) * T;
        ang = sqrt(ux * ux + uy * uy + uz * uz);
        if (ang > 1e-12) {
            sc = sin(0.5 * ang) / ang;
            cw = cos(0.5 * ang);
        } else {
            sc = 0.5;
            cw = 1.0;
        }
        dx = sc * ux;
        dy = sc * uy;
        dz = sc * uz;
        a0 = qw * cw - qx * dx - qy * dy - qz * dz;
        a1 = qw * dx + qx * cw + qy * dz - qz * dy;
        a2 = qw * dy - qx * dz + qy * cw + qz * dx;
        a3 = qw * dz + qx * dy - qy * dx + qz * cw;
        qw = a0;
        qx = a1;
        qy = a2;
        qz = a3;
    }
    if (rest) {
        s->px += ux;
        s->py += uy;
        s->pz += uz;
    } else {
        s->px = 0.0;
        s->py = 0.0;
        s->pz = 0.0;
    }
    n = sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    qw = qw / n;
    qx = qx / n;
    qy = qy / n;
    qz = qz / n;
    r0 = 1.0 - 2.0 * (qy * qy + qz * qz);
    r1 = 2.0 * (qx * qy - qw * qz);
    r2 = 2.0 * (qx * qz + qw * qy);
    r3 = 2.0 * (qx * qy + qw * qz);
    r4 = 1.0 - 2.0 * (qx * qx + qz * qz);
    r5 = 2.0 * (qy * qz - qw * qx);
    r6 = 2.0 * (qx * qz - qw * qy);
    r7 = 2.0 * (qy * qz + qw * qx);
    r8 = 1.0 - 2.0 * (qx * qx + qy * qy);

    /* velocity channel (tilt): v += T f_E; e = -v; v += k1 e; tilt turned by k2 e / g */
    if (acc_ok && 0.0 < s->tilt_n * TILT_ALPHA && s->tilt_n * TILT_ALPHA < 1.0) {
        /* start-up (from the first specific force, not a given attitude): the tilt is the running mean
           of the tilts of the specific forces so far, turned by the gyro (one reading is as noisy as
           the accelerometer); the velocity channel starts from zero velocity after it */
        if (!first) {
            double fex, fey, fez, fh;

            s->tilt_n += 1.0;
            fex = r0 * ax + r1 * ay + r2 * az;
            fey = r3 * ax + r4 * ay + r5 * az;
            fez = r6 * ax + r7 * ay + r8 * az;
            fh = sqrt(fex * fex + fey * fey);
            if (fh > 0.0) {
                const double w = atan2(fh, fez) / (s->tilt_n * fh);

                cx = w * fey;
                cy = -w * fex;
            }
        }
        s->vx = 0.0;
        s->vy = 0.0;
    } else if (acc_ok) {
        double k1v, k2v, evx, evy;
        int jv;

        if (!INERTIAL) {
            s->vx = 0.0;
            s->vy = 0.0;
        }
        s->vx += T * (r0 * ax + r1 * ay + r2 * az);
        s->vy += T * (r3 * ax + r4 * ay + r5 * az);
        s->level = 0.0;
        if (rest) {
            s->accel_time = 0.0;
            jv = 1;
        } else {
            const double vv = s->vx * s->vx + s->vy * s->vy;

            if (s->accel_time < 0.0) {
                /* after a tilt error: the motion design */
                const double t = s->accel_time + T;

                s->accel_time = t < 0.0 ? t : 0.0;
            } else if (USE_LEVELS && vv > SPEED2) {
                s->accel_time += T;
                if (s->accel_time < MAX_ACCEL_TIME) {
                    if (s->accel_time >= ACCEL_HOLD) {
                        /* longer than a hand's stroke: a sustained acceleration */
                        const double up = 1.0 + floor(log2(vv / SPEED2));
                        const double top = (double)(NVEL - 2);

                        s->level = up < top ? up : top;
                    }
                } else {
                    /* longer than an acceleration lasts: a tilt error, which only the motion design corrects */
                    s->vx = 0.0;
                    s->vy = 0.0;
                    s->accel_time = -MAX_ACCEL_TIME;
                }
            } else {
                s->accel_time = 0.0;
            }
            jv = s->level == 0.0 ? 0 : 1 + (int)s->level;
        }
        k1v = VELOCITY[jv][0];
        k2v = VELOCITY[jv][1];
        evx = -s->vx;
        evy = -s->vy;
        s->vx += k1v * evx;
        s->vy += k1v * evy;
        cx = -k2v * evy / GRAVITY;
        cy = k2v * evx / GRAVITY;
        /* tilt channel (gyro bias during motion): reads the tilt the velocity channel gives */
        if (USE_MOTION_BIAS && !rest) {
            double k1t = TILT[5], k2t = TILT[6], e1, e2, d1, d2, d3;

            s->ex -= r0 * cx + r3 * cy;
            s->ey -= r1 * cx + r4 * cy;
            s->ez -= r2 * cx + r5 * cy;
            if (TILT[4] != 0.0) {
                const double den = s->t00 + TILT[3];
                double t00, t01;

                k1t = s->t00 / den;
                k2t = s->t01 / den;
                t00 = (1.0 - k1t) * s->t00;
                t01 = (1.0 - k1t) * s->t01;
                s->t11 = s->t11 - k2t * s->t01;
                s->t00 = t00;
                s->t01 = t01;
            }
            e1 = -(r0 * s->ex + r1 * s->ey + r2 * s->ez);
            e2 = -(r3 * s->ex + r4 * s->ey + r5 * s->ez);
            d1 = r0 * e1 + r3 * e2;
            d2 = r1 * e1 + r4 * e2;
            d3 = r2 * e1 + r5 * e2;
            s->ex += k1t * d1;
            s->ey += k1t * d2;
            s->ez += k1t * d3;
            bx -= k2t * d1;
            by -= k2t * d2;
            bz -= k2t * d3;
        }
    }
    if (!rest) {
        const double t00 = s->t00 + 2.0 * T * s->t01 + T * T * s->t11 + TILT[0];
        const double t01 = s->t01 + T * s->t11 + TILT[1];

        s->t11 = s->t11 + TILT[2];
        s->t00 = t00;
        s->t01 = t01;
    }

    /* heading channel (9D): magnetic disturbance check, then the correction about ENU z */
    if (CF_ATTITUDE_NINE_D) {
        if (mag_ok) {
            const double nm = sqrt(m2);
            const double mex = r0 * mx + r1 * my + r2 * mz;
            const double mey = r3 * mx + r4 * my + r5 * mz;
            const double mez = r6 * mx + r7 * my + r8 * mz;
            double x = -mez / nm, dip, th, a;
            int dist;

            x = x < 1.0 ? x : 1.0;
            x = x > -1.0 ? x : -1.0;
            dip = asin(x);
            if (0.0 < s->tilt_n * TILT_ALPHA && s->tilt_n * TILT_ALPHA < 1.0) {
                /* the tilt's start-up: the dip read through a tilt not yet settled is not the field's,
                   so the reference starts (from the reading alone, below) once the tilt has settled */
                s->ref_n = 0.0;
            }
            if (s->ref_n * MAG_ALPHA < 1.0) {
                /* start-up: the low-pass is the running mean of the readings so far, and the reference
                   is that mean (ref_n counts the reading below, as an undisturbed one) */
                s->norm_lp += (nm - s->norm_lp) / (s->ref_n + 1.0);
                s->dip_lp += (dip - s->dip_lp) / (s->ref_n + 1.0);
                s->norm_ref = s->norm_lp;
                s->dip_ref = s->dip_lp;
            } else {
                s->norm_lp += MAG_ALPHA * (nm - s->norm_lp);
                s->dip_lp += MAG_ALPHA * (dip - s->dip_lp);
            }
            th = MAG_TOL * cos(s->dip_ref);
            dist = USE_MAG_CHECK && (fabs(s->norm_lp - s->norm_ref) > th * s->norm_ref
                                     || fabs(s->dip_lp - s->dip_ref) > th);
            if (dist) {
                /* a candidate new field: accepted once it held long enough while the sensor turned */
                if (s->new_n == 0.0) {
                    s->norm_new = s->norm_lp;
                    s->dip_new = s->dip_lp;
                    s->new_n = 1.0;
                    s->new_time = 0.0;
                    s->new_turn = 0.0;
                } else {
                    double thn;

                    s->new_n += 1.0;
                    a = 1.0 / s->new_n;
                    a = MAG_REF_ALPHA > a ? MAG_REF_ALPHA : a;
                    s->norm_new += a * (s->norm_lp - s->norm_new);
                    s->dip_new += a * (s->dip_lp - s->dip_new);
                    thn = MAG_TOL * cos(s->dip_new);
                    if (fabs(s->norm_lp - s->norm_new) <= thn * s->norm_new && fabs(s->dip_lp - s->dip_new) <= thn) {
                        s->new_time += T;
                        s->new_turn += ang;
                        if (s->new_time >= MAG_NEW_TIME && s->new_turn >= MAG_NEW_TURN) {
                            s->norm_ref = s->norm_new;
                            s->dip_ref = s->dip_new;
                            s->ref_n = s->new_n;
                            dist = 0;
                            s->new_n = 0.0;
                            s->new_time = 0.0;
                            s->new_turn = 0.0;
                            s->h01 = 0.0;   /* the new field's north is not the old one's */
                        }
                    } else {
                        s->new_n = 0.0;
                        s->new_time = 0.0;
                        s->new_turn = 0.0;
                    }
                }
            } else {
                s->ref_n += 1.0;
                a = 1.0 / s->ref_n;
                a = MAG_REF_ALPHA > a ? MAG_REF_ALPHA : a;
                s->norm_ref += a * (s->norm_lp - s->norm_ref);
                s->dip_ref += a * (s->dip_lp - s->dip_ref);
                s->new_n = 0.0;
                s->new_time = 0.0;
                s->new_turn = 0.0;
            }
            s->disturbed = dist ? 1.0 : 0.0;
            if (!dist && sqrt(mex * mex + mey * mey) > 1e-9 * nm) {
                const double eh = wrap_angle(NORTH - atan2(mey, mex));
                double hk1 = HEADING[5], hk2 = HEADING[6];

                if (HEADING[4] != 0.0) {
                    const double den = s->h00 + HEADING[3];
                    double h00, h01;

                    hk1 = s->h00 / den;
                    hk2 = s->h01 / den;
                    h00 = (1.0 - hk1) * s->h00;
                    h01 = (1.0 - hk1) * s->h01;
                    s->h11 = s->h11 - hk2 * s->h01;
                    s->h00 = h00;
                    s->h01 = h01;
                }
                cz = hk1 * eh;
                dz = hk2 * eh;
                bx -= r6 * dz;
                by -= r7 * dz;
                bz -= r8 * dz;
            }
        }
        {
            const double h00 = s->h00 + 2.0 * T * s->h01 + T * T * s->h11 + HEADING[0];
            const double h01 = s->h01 + T * s->h11 + HEADING[1];

            s->h11 = s->h11 + HEADING[2];
            s->h00 = h00;
            s->h01 = h01;
        }
    }

    /* corrections in ENU: q <- exp(c / 2) (x) q; the velocity turns with the heading */
    ang_c = sqrt(cx * cx + cy * cy + cz * cz);
    if (ang_c > 0.0) {
        double vx;

        sc = sin(0.5 * ang_c) / ang_c;
        cw = cos(0.5 * ang_c);
        dx = sc * cx;
        dy = sc * cy;
        dz = sc * cz;
        a0 = cw * qw - dx * qx - dy * qy - dz * qz;
        a1 = cw * qx + dx * qw + dy * qz - dz * qy;
        a2 = cw * qy - dx * qz + dy * qw + dz * qx;
        a3 = cw * qz + dx * qy - dy * qx + dz * qw;
        qw = a0;
        qx = a1;
        qy = a2;
        qz = a3;
        vx = s->vx - cz * s->vy;
        s->vy = s->vy + cz * s->vx;
        s->vx = vx;
    }

    /* zero-rotation channel at rest: reads "no rotation since rest began" */
    if (rest) {
        double k1r = REST[5], k2r = REST[6], e1, e2, e3, hx, hy, hz, ang_r;

        if (!was_rest) {
            s->r00 = HOLD_VAR;
            s->r01 = 0.0;
        }
        if (REST[4] != 0.0) {
            const double den = s->r00 + REST[3];
            double r00, r01;

            k1r = s->r00 / den;
            k2r = s->r01 / den;
            r00 = (1.0 - k1r) * s->r00;
            r01 = (1.0 - k1r) * s->r01;
            s->r11 = s->r11 - k2r * s->r01;
            s->r00 = r00;
            s->r01 = r01;
        }
        e1 = -s->px;
        e2 = -s->py;
        e3 = -s->pz;
        s->px += k1r * e1;
        s->py += k1r * e2;
        s->pz += k1r * e3;
        hx = 0.5 * k1r * e1;
        hy = 0.5 * k1r * e2;
        hz = 0.5 * k1r * e3;
        ang_r = sqrt(hx * hx + hy * hy + hz * hz);
        if (ang_r > 1e-12) {
            sc = sin(ang_r) / ang_r;
            cw = cos(ang_r);
        } else {
            sc = 1.0;
            cw = 1.0;
        }
        dx = sc * hx;
        dy = sc * hy;
        dz = sc * hz;
        a0 = qw * cw - qx * dx - qy * dy - qz * dz;
        a1 = qw * dx + qx * cw + qy * dz - qz * dy;
        a2 = qw * dy - qx * dz + qy * cw + qz * dx;
        a3 = qw * dz + qx * dy - qy * dx + qz * cw;
        qw = a0;
        qx = a1;
        qy = a2;
        qz = a3;
        bx -= k2r * e1;
        by -= k2r * e2;
        bz -= k2r * e3;
        {
            const double r00 = s->r00 + 2.0 * T * s->r01 + T * T * s->r11 + REST[0];
            const double r01 = s->r01 + T * s->r11 + REST[1];

            s->r11 = s->r11 + REST[2];
            s->r00 = r00;
            s->r01 = r01;
        }
        /* the bias is now known to the zero-rotation channel's variance: so it is to the others */
        s->t00 = TILT[3];
        s->t01 = 0.0;
        s->ex = 0.0;
        s->ey = 0.0;
        s->ez = 0.0;
        if (s->r11 < s->t11)
            s->t11 = s->r11;
        if (s->r11 < s->h11) {
            s->h01 *= sqrt(s->r11 / s->h11);
            s->h11 = s->r11;
        }
    } else {
        s->r11 += REST[2];
    }
    n = sqrt(qw * qw + qx * qx + qy * qy + qz * qz);
    s->qw = qw / n;
    s->qx = qx / n;
    s->qy = qy / n;
    s->qz = qz / n;
    s->bx = bx;
    s->by = by;
    s->bz = bz;
    if (s->qw < 0.0) {
        q_out[0] = -s->qw;
        q_out[1] = -s->qx;
        q_out[2] = -s->qy;
        q_out[3] = -s->qz;
    } else {
        q_out[0] = s->qw;
        q_out[1] = s->qx;
        q_out[2] = s->qy;
        q_out[3] = s->qz;
    }
}
