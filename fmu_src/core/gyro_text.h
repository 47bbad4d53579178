/* Numbers in messages, written as Python's repr writes them (the library and the FMUs
 * word their refusals alike): the shortest text that reads back as the same double. */
#ifndef GYRO_TEXT_H
#define GYRO_TEXT_H

#define GYRO_REAL_TEXT 40

#include <stddef.h>

/* math.pi (every core file includes this header; C99 has no M_PI). */
#ifndef GYRO_PI
#define GYRO_PI 3.141592653589793
#endif

/* Returns buf (or a literal for nan and inf). */
const char *gyro_real_text(double v, char buf[GYRO_REAL_TEXT]);

/* Append text to the message msg (capacity n), "; "-separated from what it holds. */
void gyro_text_add(char *msg, size_t n, const char *text);

#endif
