/* Threads layer internals. */
#ifndef I2M_THREADS_IMPL_H
#define I2M_THREADS_IMPL_H

#include "i2m/threads.h"

typedef struct i2m_pinning i2m_pinning_t;
i2m_pinning_t *pinning_open(void);
void pinning_close(i2m_pinning_t *p);
int pinning_cores(const i2m_pinning_t *p);
/** Binds the calling thread to the k-th allowed core; returns the core or -1. */
int pinning_bind_thread(i2m_pinning_t *p, int k);
/** Lets the calling thread run on any core the process may use. */
void pinning_float_thread(i2m_pinning_t *p);

#endif
