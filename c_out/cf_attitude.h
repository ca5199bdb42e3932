/*
 * cf_attitude.h - the attitude filter's state and functions
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
#ifndef CF_ATTITUDE_H
#define CF_ATTITUDE_H

#ifdef __cplusplus
extern "C" {
#endif

/* sample rate (Hz) the tables were designed for; 1: magnetometer used (9D), 0: 6D */
#define CF_ATTITUDE_RATE_HZ 0x1.9000000000000p+6
#define CF_ATTITUDE_NINE_D 1

/*
 * The filter state: plain data, every field a double, in the order of
 * cfdesign.nav.attitude_filter.STATE_FIELDS (AttitudeFilter.state() gives the same names).
 * qw, qx, qy, qz: attitude, body -> ENU; bx, by, bz: gyro bias, body frame, rad/s.
 */
typedef struct {
    double qw;
    double qx;
    double qy;
    double qz;
    double bx;
    double by;
    double bz;
    double vx;
    double vy;
    double ex;
    double ey;
    double ez;
    double px;
    double py;
    double pz;
    double gx;
    double gy;
    double gz;
    double fx;
    double fy;
    double fz;
    double gyro_dev;
    double accel_dev;
    double rest_time;
    double r00;
    double r01;
    double r11;
    double t00;
    double t01;
    double t11;
    double h00;
    double h01;
    double h11;
    double norm_lp;
    double dip_lp;
    double norm_ref;
    double dip_ref;
    double ref_n;
    double norm_new;
    double dip_new;
    double new_n;
    double new_time;
    double new_turn;
    double disturbed;
    double level;
    double accel_time;
    double tilt_n;
    double lgx;
    double lgy;
    double lgz;
    double started;
    double missing_gyr;
    double missing_acc;
    double missing_mag;
} cf_attitude_state;

/* The state before the first sample (the filter's priors). */
void cf_attitude_init(cf_attitude_state *s);

/*
 * One sample, body frame: gyr (rad/s), acc (specific force, m/s^2), mag (field, any unit;
 * NULL: no reading; ignored in 6D).  A non-finite or impossible reading is missing and
 * counted (missing_gyr, missing_acc, missing_mag).  q_out: the attitude [w, x, y, z]
 * (w >= 0), body -> ENU.
 */
void cf_attitude_step(cf_attitude_state *s, const double gyr[3], const double acc[3], const double *mag,
                    double q_out[4]);

#ifdef __cplusplus
}
#endif

#endif /* CF_ATTITUDE_H */
