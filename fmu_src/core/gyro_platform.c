/* The stabilized platform's step (gyro_platform.h). */
#include "gyro_platform.h"

#include <math.h>
#include <stdio.h>

int gyro_platform_problems(const GyroPlatformParams *p, char *msg, size_t n) {
    if (!(isfinite(p->J) && p->J > 0.0) || !(isfinite(p->c) && p->c > 0.0)) {
        snprintf(msg, n, "platform: J=%g kg m2 and c=%g N m s/rad must be finite and > 0",
                 p->J, p->c);
        return 1;
    }
    if (!(isfinite(p->Kp) && p->Kp >= 0.0) || !(isfinite(p->Ki) && p->Ki >= 0.0)) {
        snprintf(msg, n, "platform: gains Kp=%g and Ki=%g must be finite and >= 0", p->Kp,
                 p->Ki);
        return 1;
    }
    if (n) msg[0] = '\0';
    return 0;
}

void gyro_platform_step(GyroPlatform *s, const GyroPlatformParams *p, double w_b,
                        double w_meas, double h) {
    s->I += w_meas * h;
    s->tau = -p->Kp * w_meas - p->Ki * s->I;
    const double w_inf = w_b + s->tau / p->c; /* where w settles with these held */
    const double a = exp(-p->c * h / p->J);
    s->theta += w_inf * h + (s->w - w_inf) * (1.0 - a) * p->J / p->c;
    s->w = w_inf + (s->w - w_inf) * a;
}
