#include "gyro_text.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *gyro_real_text(double v, char buf[GYRO_REAL_TEXT]) {
    if (isnan(v)) return "nan";
    if (isinf(v)) return v > 0 ? "inf" : "-inf";
    int digits = 1;
    for (; digits < 17; digits++) {
        snprintf(buf, GYRO_REAL_TEXT, "%.*g", digits, v);
        if (strtod(buf, NULL) == v) break;
    }
    snprintf(buf, GYRO_REAL_TEXT, "%.*g", digits, v);
    const char *e = strchr(buf, 'e');
    if (e) { /* repr uses positional notation for exponents -4 .. 15 */
        const int exponent = atoi(e + 1);
        if (exponent >= -4 && exponent < 16) {
            const int decimals = digits - 1 - exponent;
            snprintf(buf, GYRO_REAL_TEXT, "%.*f", decimals > 0 ? decimals : 0, v);
        } else {
            return buf;
        }
    }
    if (!strchr(buf, '.')) strcat(buf, ".0");
    return buf;
}

void gyro_text_add(char *msg, size_t n, const char *text) {
    size_t used = strlen(msg);
    if (used && used + 2 < n) {
        strcat(msg, "; ");
        used += 2;
    }
    if (used < n) snprintf(msg + used, n - used, "%s", text);
}
