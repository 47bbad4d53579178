/* What the FMI layer's instance files share (instance.c, instance_values.c,
 * instance_states.c); not part of the layer's API (instance.h). */
#ifndef GYRO_INSTANCE_INTERNAL_H
#define GYRO_INSTANCE_INTERNAL_H

#include <stddef.h>
#include <stdint.h>

#include "instance.h"

#define STATE_MAGIC 0x47595353u /* "GYSS" */

/* An FMU state: a copy of the instance's mode, times, failure text and model data. */
struct StateCopy {
    uint32_t magic;
    Instance *owner;
    StateCopy *next;
    Mode mode;
    double start_time, time;
    char failed[GYRO_MESSAGE_SIZE];
    unsigned char data[]; /* model->data_size bytes */
};

/* Why `value` is not acceptable for v (non-zero, msg says it with the remedy), or 0:
 * the words of gyro_fmu.model.interfaces.Var. */
int inst_range_problem(const GyroVariable *v, double value, char *msg, size_t n);

#endif
