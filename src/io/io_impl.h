/* io layer internals (layer 7): a buffered output file with checked writes, little-endian
 * helpers, and the numbering of interface label pairs shared by the Medit and Gmsh writers.
 * Not part of the public API. */
#ifndef I2M_IO_IMPL_H
#define I2M_IO_IMPL_H

#include "i2m/io.h"

#include <stdio.h>

/** Output file with a large buffer.  The first failure is kept in err (with a message
 *  naming the file); later calls do nothing, so writers check err once per section. */
typedef struct {
  i2m_outfile_t out; /* written under a temporary name, renamed into place by io_out_close */
  FILE *f;          /* out.f */
  const char *path; /* borrowed */
  char *buf;        /* owned: [cap] bytes */
  size_t len, cap;
  i2m_err_t err;
  int64_t written;          /* bytes written so far */
  i2m_progress_t progress;  /* a line every 2 s while a large file is written */
} io_out_t;

/** Opens @p path for binary writing. */
i2m_err_t io_out_open(io_out_t *o, const char *path);
/** Flushes and closes; returns the first error met.  The file appears under its name only
 *  when everything was written; on error the previous file of that name is untouched. */
i2m_err_t io_out_close(io_out_t *o);
/** Writes the buffer to the file. */
void io_out_flush(io_out_t *o);
/** Appends n bytes. */
void io_out_put(io_out_t *o, const void *p, size_t n);
/** Appends formatted text (at most 4 KiB per call). */
void io_out_printf(io_out_t *o, const char *fmt, ...) I2M_PRINTF(2, 3);
/** A pointer where n (<= cap) bytes may be written; io_out_commit(o, n) makes them count.
 *  Returns NULL when the file is already in error. */
char *io_out_reserve(io_out_t *o, size_t n);
static inline void io_out_commit(io_out_t *o, size_t n) { o->len += n; }

/** 1 when the host stores integers little-endian. */
static inline int io_host_little(void)
{
  const uint16_t one = 1;
  return *(const unsigned char *)&one == 1;
}
/** Stores v little-endian at p (8, 4 bytes). */
static inline void io_le64(char *p, uint64_t v)
{
  for (int b = 0; b < 8; b++) p[b] = (char)(unsigned char)(v >> (8 * b));
}
static inline void io_le32(char *p, uint32_t v)
{
  for (int b = 0; b < 4; b++) p[b] = (char)(unsigned char)(v >> (8 * b));
}

/** Writes the decimal form of v at p; returns the number of characters (no NUL). */
int io_fmt_i64(char *p, int64_t v);

/** Distinct interface label pairs of m, sorted by (a,b): pairs [npairs][2]; tri_pair [ntri]
 *  index of each triangle's pair.  Both owned by the caller. */
i2m_err_t io_interface_pairs(const i2m_tetmesh_t *m, int64_t **pairs, int64_t *npairs,
                             int32_t **tri_pair);

/* The writers (opts: never NULL here). */
i2m_err_t io_write_vtu(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts);
/** The same with material Int64 (wide) or Int32 (the pieces of a .pvtu must agree). */
i2m_err_t io_write_vtu_typed(const i2m_tetmesh_t *m, const char *path, int wide, const i2m_write_opts_t *opts);
i2m_err_t io_write_medit(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts);
i2m_err_t io_write_gmsh(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts);

#endif
