/* Numbers in messages, written as Python's repr writes them (the library and the FMUs
 * word their refusals alike): the shortest text that reads back as the same double. */
#ifndef GYRO_TEXT_H
#define GYRO_TEXT_H

#define GYRO_REAL_TEXT 40

/* Returns buf (or a literal for nan and inf). */
const char *gyro_real_text(double v, char buf[GYRO_REAL_TEXT]);

#endif
