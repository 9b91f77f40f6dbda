/* io layer: buffered, checked output files; format dispatch by extension; interface label
 * pair numbering shared by the writers. */
#include "io_impl.h"

#include <errno.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <unistd.h>

#define IO_BUF_BYTES ((size_t)8 << 20)

i2m_err_t io_out_open(io_out_t *o, const char *path)
{
  memset(o, 0, sizeof *o);
  o->path = path;
  I2M_CALL(i2m_malloc(IO_BUF_BYTES, 1, &o->buf));
  o->cap = IO_BUF_BYTES;
  i2m_err_t err = i2m_outfile_open(&o->out, path, "wb");
  if (err != I2M_OK) {
    i2m_free(&o->buf);
    return err;
  }
  o->f = o->out.f;
  i2m_progress_begin(&o->progress, "writing", "MB"); /* (the size is not known before) */
  return I2M_OK;
}

void io_out_flush(io_out_t *o)
{
  if (o->err != I2M_OK || o->len == 0) {
    o->len = 0;
    return;
  }
  errno = 0;
  size_t w = fwrite(o->buf, 1, o->len, o->f);
  o->written += (int64_t)w;
  i2m_progress_update(&o->progress, o->written >> 20);
  if (w != o->len) {
    int e = errno;
    o->err = I2M_ERROR(I2M_ERR_IO, "%s: write failed after %zu of %zu bytes: %s", o->path, w,
                       o->len, e ? strerror(e) : "short write");
  }
  o->len = 0;
}

char *io_out_reserve(io_out_t *o, size_t n)
{
  if (o->err != I2M_OK) return NULL;
  if (o->cap - o->len < n) io_out_flush(o);
  if (o->err != I2M_OK || n > o->cap) return NULL;
  return o->buf + o->len;
}

void io_out_put(io_out_t *o, const void *p, size_t n)
{
  const char *c = p;
  while (n > 0 && o->err == I2M_OK) {
    if (o->len == o->cap) io_out_flush(o);
    size_t k = o->cap - o->len < n ? o->cap - o->len : n;
    memcpy(o->buf + o->len, c, k);
    o->len += k;
    c += k;
    n -= k;
  }
}

void io_out_printf(io_out_t *o, const char *fmt, ...)
{
  char *p = io_out_reserve(o, 4096);
  if (!p) return;
  va_list ap;
  va_start(ap, fmt);
  int k = vsnprintf(p, 4096, fmt, ap);
  va_end(ap);
  if (k < 0 || k >= 4096) {
    o->err = I2M_ERROR(I2M_ERR_INTERNAL, "%s: formatted line too long", o->path);
    return;
  }
  o->len += (size_t)k;
}

i2m_err_t io_out_close(io_out_t *o)
{
  if (!o->f) return o->err;
  io_out_flush(o);
  i2m_progress_end(&o->progress, o->written >> 20);
  if (o->err == I2M_OK) o->err = i2m_outfile_commit(&o->out);
  else i2m_outfile_abandon(&o->out);
  o->f = NULL;
  i2m_free(&o->buf);
  return o->err;
}

int io_fmt_i64(char *p, int64_t v)
{
  char tmp[24];
  int n = 0, k = 0;
  uint64_t u = v < 0 ? (uint64_t)0 - (uint64_t)v : (uint64_t)v;
  do {
    tmp[n++] = (char)('0' + (int)(u % 10));
    u /= 10;
  } while (u);
  if (v < 0) p[k++] = '-';
  while (n) p[k++] = tmp[--n];
  return k;
}

static int cmp_pair(const void *a, const void *b)
{
  const int64_t *x = a, *y = b;
  if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
  return (x[1] > y[1]) - (x[1] < y[1]);
}

i2m_err_t io_interface_pairs(const i2m_tetmesh_t *m, int64_t **pairs, int64_t *npairs,
                             int32_t **tri_pair)
{
  int64_t *p = NULL;
  i2m_err_t err = I2M_OK;
  *pairs = NULL;
  *tri_pair = NULL;
  *npairs = 0;
  if (m->ntri == 0) return I2M_OK;
  I2M_CALL(i2m_malloc((size_t)m->ntri * 2, sizeof *p, &p));
  memcpy(p, m->tri_label, (size_t)m->ntri * 2 * sizeof *p);
  qsort(p, (size_t)m->ntri, 2 * sizeof *p, cmp_pair);
  int64_t n = 0;
  for (int64_t i = 0; i < m->ntri; i++)
    if (n == 0 || cmp_pair(p + 2 * i, p + 2 * (n - 1)) != 0) {
      p[2 * n] = p[2 * i];
      p[2 * n + 1] = p[2 * i + 1];
      n++;
    }
  I2M_CALL_GOTO(err, fail, i2m_realloc((size_t)n * 2, sizeof *p, &p));
  I2M_CALL_GOTO(err, fail, i2m_malloc((size_t)m->ntri, sizeof **tri_pair, tri_pair));
  for (int64_t i = 0; i < m->ntri; i++) {
    int64_t lo = 0, hi = n - 1; /* binary search: the pair is present */
    while (lo < hi) {
      int64_t mid = (lo + hi) / 2;
      if (cmp_pair(p + 2 * mid, m->tri_label + 2 * i) < 0)
        lo = mid + 1;
      else
        hi = mid;
    }
    (*tri_pair)[i] = (int32_t)lo;
  }
  *pairs = p;
  *npairs = n;
  return I2M_OK;
fail:
  i2m_free(&p);
  return err;
}

i2m_format_t i2m_format_from_path(const char *path)
{
  const char *dot = path ? strrchr(path, '.') : NULL;
  if (!dot || strchr(dot, '/')) return I2M_FORMAT_UNKNOWN;
  if (strcasecmp(dot, ".vtu") == 0) return I2M_FORMAT_VTU;
  if (strcasecmp(dot, ".mesh") == 0) return I2M_FORMAT_MEDIT;
  if (strcasecmp(dot, ".msh") == 0) return I2M_FORMAT_GMSH;
  if (strcasecmp(dot, ".pvtu") == 0) return I2M_FORMAT_PVTU;
  return I2M_FORMAT_UNKNOWN;
}

/* Indices in range, so that a writer never emits a file that refers to missing vertices. */
static i2m_err_t check_mesh(const i2m_tetmesh_t *m, const char *path)
{
  I2M_CHECK(m && m->nv >= 0 && m->nt >= 0 && m->ntri >= 0, I2M_ERR_INTERNAL,
            "%s: invalid mesh object", path);
  I2M_CHECK(m->nv <= INT32_MAX, I2M_ERR_UNSUPPORTED, "%s: %lld vertices exceed 32-bit ids",
            path, (long long)m->nv);
  for (int64_t i = 0; i < 4 * m->nt; i++)
    I2M_CHECK(m->tet[i] >= 0 && m->tet[i] < m->nv, I2M_ERR_INTERNAL,
              "%s: tetrahedron %lld refers to vertex %d of %lld", path, (long long)(i / 4),
              (int)m->tet[i], (long long)m->nv);
  for (int64_t i = 0; i < 3 * m->ntri; i++)
    I2M_CHECK(m->tri[i] >= 0 && m->tri[i] < m->nv, I2M_ERR_INTERNAL,
              "%s: triangle %lld refers to vertex %d of %lld", path, (long long)(i / 3),
              (int)m->tri[i], (long long)m->nv);
  return I2M_OK;
}

/* An output file can be written: not a directory, writable, or a new name in a writable
 * directory. */
static i2m_err_t check_file_writable(const char *path)
{
  struct stat st;
  if (stat(path, &st) == 0) {
    I2M_CHECK(!S_ISDIR(st.st_mode), I2M_ERR_IO, "%s: is a directory, not an output file", path);
    I2M_CHECK(access(path, W_OK) == 0, I2M_ERR_IO, "%s: cannot write: %s", path, strerror(errno));
    return I2M_OK;
  }
  char dir[4096];
  I2M_CHECK(i2m_path_dir(path, dir, sizeof dir), I2M_ERR_IO, "%s: path too long", path);
  I2M_CHECK(stat(dir, &st) == 0 && S_ISDIR(st.st_mode), I2M_ERR_IO,
            "%s: cannot write: the directory %s does not exist", path, dir);
  I2M_CHECK(access(dir, W_OK) == 0, I2M_ERR_IO, "%s: cannot write into %s: %s", path, dir, strerror(errno));
  return I2M_OK;
}

i2m_err_t i2m_mesh_check_writable(const char *path)
{
  I2M_CHECK(i2m_format_from_path(path) != I2M_FORMAT_UNKNOWN, I2M_ERR_ARG,
            "%s: unknown output format; use a .vtu, .pvtu, .mesh or .msh file name", path);
  I2M_CALL(check_file_writable(path));
  char side[4096];
  if (i2m_format_from_path(path) == I2M_FORMAT_MEDIT) {
    I2M_CHECK(i2m_mesh_side_path(path, side, sizeof side), I2M_ERR_ARG, "%s: file name too long", path);
    I2M_CALL(check_file_writable(side)); /* its JSON side file */
  }
  return I2M_OK;
}

i2m_write_opts_t i2m_write_opts_default(void)
{
  const char *ascii = getenv("I2M_MSH_ASCII");
  return (i2m_write_opts_t){.names = NULL, .msh_version = 41, .ascii = ascii && strcmp(ascii, "1") == 0, .compress = true};
}

i2m_err_t i2m_mesh_write(const i2m_tetmesh_t *m, const char *path, const i2m_write_opts_t *opts)
{
  const i2m_write_opts_t o = opts ? *opts : i2m_write_opts_default();
  I2M_CHECK(path && *path, I2M_ERR_ARG, "empty output file name");
  i2m_format_t fmt = i2m_format_from_path(path);
  I2M_CHECK(fmt != I2M_FORMAT_UNKNOWN && fmt != I2M_FORMAT_PVTU, I2M_ERR_ARG,
            "%s: unknown mesh format (expected a .vtu, .mesh or .msh file name)", path);
  I2M_CALL(check_mesh(m, path));
  if (fmt == I2M_FORMAT_VTU) return io_write_vtu(m, path, &o);
  if (fmt == I2M_FORMAT_MEDIT) return io_write_medit(m, path, &o);
  return io_write_gmsh(m, path, &o);
}
