/* i2m-check: readers for the mesh files i2m writes (and simple variants of them).
 *   .vtu   VTK XML UnstructuredGrid: appended data (raw or base64, VTK's default) with
 *          UInt32 or UInt64 headers, inline ascii or base64 DataArrays (the base64 header
 *          encoded apart from the data or with it), each raw or zlib-compressed (compressor="vtkZLibDataCompressor":
 *          a header [blocks, block size, last partial block size or 0, compressed size of
 *          each block], then the blocks, each inflated on its own).  Tetrahedra (type 10) and
 *          cell data "material" (else the first cell array); other cells are skipped; the
 *          point data "GlobalNodeId" when present (the pieces of a distributed mesh).
 *   .pvtu  the list of pieces (<Piece Source=...>) of a PUnstructuredGrid; the pieces are
 *          read as .vtu and stitched by pvtu.c.
 *   .mesh  Medit ASCII: Vertices, Tetrahedra, Triangles, then End (required: a file cut
 *          between sections would otherwise read as a smaller mesh); the comments
 *          "# i2m interface N = labels A B" give each triangle ref its label pair.
 *   .msh   Gmsh 4.1 or 2.2, ASCII or binary: $PhysicalNames ("interface_A_B" names give the
 *          pairs), $Entities (4.1: physical tag of each entity), $Nodes, $Elements (tets and
 *          triangles; 2.2: each element's first tag is its physical tag).
 * Every read is bounded by the file size: a truncated or corrupt file gives an error that
 * names the file, never a crash.  Vertex ids are kept as found (validity checks the range). */
#include "check.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <zlib.h>

typedef struct {
  const char *p, *end; /* borrowed: cursor and end of the file buffer (NUL after end) */
  const char *path;    /* borrowed */
  int swap;            /* binary values are big-endian */
  ck_progress_t *pr;   /* or NULL: bytes parsed, from base */
  const char *base;
  uint32_t tick;
} rd_t;

/* Every 65536 values read, the bytes parsed so far to the progress line (if any). */
static inline void rd_tick(rd_t *r)
{
  if (r->pr && (++r->tick & 0xFFFF) == 0) ck_progress_to(r->pr, r->p - r->base);
}

void ck_mesh_free(ck_mesh_t *m)
{
  i2m_free(&m->xyz);
  i2m_free(&m->tet);
  i2m_free(&m->tet_label);
  i2m_free(&m->tri);
  i2m_free(&m->tri_label);
  i2m_free(&m->gid);
  ck_stitch_free(&m->stitch);
  memset(m, 0, sizeof *m);
}

static i2m_err_t read_file(const char *path, char **buf, size_t *len)
{
  FILE *f = fopen(path, "rb");
  *buf = NULL;
  if (!f) return I2M_ERROR(I2M_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
  size_t cap = (size_t)1 << 20, n = 0;
  char *b = NULL;
  i2m_err_t err = i2m_malloc(cap + 1, 1, &b);
  while (err == I2M_OK) {
    if (n == cap) {
      cap *= 2;
      err = i2m_realloc(cap + 1, 1, &b);
      if (err != I2M_OK) break;
    }
    size_t k = fread(b + n, 1, cap - n, f);
    n += k;
    if (k == 0) {
      if (ferror(f)) err = I2M_ERROR(I2M_ERR_IO, "%s: read error", path);
      break;
    }
  }
  fclose(f);
  if (err != I2M_OK) {
    i2m_free(&b);
    return err;
  }
  b[n] = '\0';
  *buf = b;
  *len = n;
  return I2M_OK;
}

/* ---- cursor helpers ---- */
static void rd_ws(rd_t *r)
{
  while (r->p < r->end && (*r->p == ' ' || *r->p == '\t' || *r->p == '\n' || *r->p == '\r'))
    r->p++;
}

static int rd_i64(rd_t *r, int64_t *v)
{
  rd_ws(r);
  if (r->p >= r->end) return 0;
  char *e;
  errno = 0;
  long long x = strtoll(r->p, &e, 10);
  if (e == r->p || errno || e > r->end) return 0;
  r->p = e;
  *v = x;
  rd_tick(r);
  return 1;
}

static int rd_f64(rd_t *r, double *v)
{
  rd_ws(r);
  if (r->p >= r->end) return 0;
  char *e;
  double x = strtod(r->p, &e);
  if (e == r->p || e > r->end) return 0;
  r->p = e;
  *v = x;
  rd_tick(r);
  return 1;
}

/* Next whitespace-delimited word (at most size-1 characters). */
static int rd_word(rd_t *r, char *w, size_t size)
{
  rd_ws(r);
  size_t n = 0;
  while (r->p < r->end && *r->p != ' ' && *r->p != '\t' && *r->p != '\n' && *r->p != '\r') {
    if (n + 1 < size) w[n++] = *r->p;
    r->p++;
  }
  w[n] = '\0';
  return n > 0;
}

static void rd_line_end(rd_t *r)
{
  while (r->p < r->end && *r->p != '\n') r->p++;
  if (r->p < r->end) r->p++;
}

static int rd_bin(rd_t *r, void *dst, size_t n)
{
  if ((size_t)(r->end - r->p) < n) return 0;
  memcpy(dst, r->p, n);
  if (r->swap) {
    unsigned char *d = dst, t;
    for (size_t i = 0; i < n / 2; i++) {
      t = d[i];
      d[i] = d[n - 1 - i];
      d[n - 1 - i] = t;
    }
  }
  r->p += n;
  rd_tick(r);
  return 1;
}

static const char *find_str(const char *p, const char *end, const char *s)
{
  size_t n = strlen(s);
  for (; p + n <= end; p++)
    if (*p == *s && memcmp(p, s, n) == 0) return p;
  return NULL;
}

static const char *find_last_str(const char *p, const char *end, const char *s)
{
  size_t n = strlen(s), len = (size_t)(end - p);
  for (size_t i = len >= n ? len - n + 1 : 0; i-- > 0;)
    if (p[i] == *s && memcmp(p + i, s, n) == 0) return p + i;
  return NULL;
}

/* Checks that a count of items of at least min_bytes each fits in what is left. */
static int count_fits(const rd_t *r, int64_t n, int64_t min_bytes)
{
  return n >= 0 && n <= (int64_t)(r->end - r->p) / min_bytes;
}

/* ==================================== Medit ==================================== */

typedef struct {
  int64_t *ref, *a, *b; /* owned: interface number -> labels */
  int64_t n, cap;
} medit_map_t;

static i2m_err_t medit_comment(rd_t *r, medit_map_t *map)
{
  const char *eol = r->p;
  while (eol < r->end && *eol != '\n') eol++;
  static const char key[] = "# i2m interface ";
  size_t kl = sizeof key - 1;
  if ((size_t)(eol - r->p) > kl && memcmp(r->p, key, kl) == 0) {
    rd_t s = {r->p + kl, eol, r->path, 0, NULL, NULL, 0};
    int64_t n, a, b;
    char eq[8], lab[16];
    if (rd_i64(&s, &n) && rd_word(&s, eq, sizeof eq) && strcmp(eq, "=") == 0 &&
        rd_word(&s, lab, sizeof lab) && strcmp(lab, "labels") == 0 && rd_i64(&s, &a) &&
        rd_i64(&s, &b)) {
      if (map->n == map->cap) {
        map->cap = map->cap ? 2 * map->cap : 64;
        I2M_CALL(i2m_realloc((size_t)map->cap, sizeof(int64_t), &map->ref));
        I2M_CALL(i2m_realloc((size_t)map->cap, sizeof(int64_t), &map->a));
        I2M_CALL(i2m_realloc((size_t)map->cap, sizeof(int64_t), &map->b));
      }
      map->ref[map->n] = n;
      map->a[map->n] = a < b ? a : b;
      map->b[map->n] = a < b ? b : a;
      map->n++;
    }
  }
  r->p = eol;
  return I2M_OK;
}

/* Reads n elements of nper ids + ref; ids become 0-based. */
static i2m_err_t medit_elements(rd_t *r, const char *kw, int nper, int64_t *n, int64_t **ids,
                                int64_t **ref)
{
  I2M_CHECK(rd_i64(r, n) && count_fits(r, *n, 2 * (nper + 1)), I2M_ERR_INPUT,
            "%s: %s: bad or truncated element count", r->path, kw);
  i2m_free(ids);
  i2m_free(ref);
  I2M_CALL(i2m_malloc((size_t)*n * (size_t)nper, sizeof(int64_t), ids));
  I2M_CALL(i2m_malloc((size_t)*n, sizeof(int64_t), ref));
  for (int64_t e = 0; e < *n; e++) {
    for (int j = 0; j < nper; j++) {
      int64_t v;
      I2M_CHECK(rd_i64(r, &v), I2M_ERR_INPUT, "%s: %s: truncated or malformed at element %lld of %lld",
                r->path, kw, (long long)(e + 1), (long long)*n);
      (*ids)[e * nper + j] = v > INT64_MIN ? v - 1 : -1;
    }
    I2M_CHECK(rd_i64(r, &(*ref)[e]), I2M_ERR_INPUT,
              "%s: %s: truncated or malformed at element %lld of %lld", r->path, kw,
              (long long)(e + 1), (long long)*n);
  }
  return I2M_OK;
}

static i2m_err_t medit_skip(rd_t *r, const char *kw, int per)
{
  int64_t n;
  double x;
  I2M_CHECK(rd_i64(r, &n) && count_fits(r, n, 2 * per), I2M_ERR_INPUT,
            "%s: %s: bad or truncated count", r->path, kw);
  for (int64_t i = 0; i < n * per; i++)
    I2M_CHECK(rd_f64(r, &x), I2M_ERR_INPUT, "%s: %s: truncated", r->path, kw);
  return I2M_OK;
}

static int medit_skip_per(const char *kw)
{
  static const struct {
    const char *kw;
    int per;
  } t[] = {{"Edges", 3},         {"Corners", 1},          {"RequiredVertices", 1},
           {"Ridges", 1},        {"RequiredEdges", 1},    {"Quadrilaterals", 5},
           {"Hexahedra", 9},     {"Prisms", 7},           {"Pyramids", 6},
           {"Normals", 3},       {"NormalAtVertices", 2}, {"Tangents", 3},
           {"TangentAtVertices", 2}, {"SubDomainFromMesh", 4}, {"RequiredTriangles", 1},
           {"RequiredTetrahedra", 1}};
  for (size_t i = 0; i < sizeof t / sizeof t[0]; i++)
    if (strcmp(kw, t[i].kw) == 0) return t[i].per;
  return 0;
}

static i2m_err_t medit_keyword(rd_t *r, const char *kw, ck_mesh_t *m, int64_t **tri_ref,
                               int *dim, int *done)
{
  int64_t x;
  if (strcmp(kw, "MeshVersionFormatted") == 0) {
    I2M_CHECK(rd_i64(r, &x) && x >= 1 && x <= 4, I2M_ERR_INPUT,
              "%s: bad MeshVersionFormatted", r->path);
  } else if (strcmp(kw, "Dimension") == 0) {
    I2M_CHECK(rd_i64(r, &x), I2M_ERR_INPUT, "%s: bad Dimension", r->path);
    I2M_CHECK(x == 3, I2M_ERR_UNSUPPORTED, "%s: Dimension %lld (only 3D meshes are checked)",
              r->path, (long long)x);
    *dim = 3;
  } else if (strcmp(kw, "Vertices") == 0) {
    I2M_CHECK(*dim == 3, I2M_ERR_INPUT, "%s: Vertices before Dimension 3", r->path);
    I2M_CHECK(rd_i64(r, &m->nv) && count_fits(r, m->nv, 8), I2M_ERR_INPUT,
              "%s: Vertices: bad or truncated count", r->path);
    i2m_free(&m->xyz);
    I2M_CALL(i2m_malloc((size_t)m->nv * 3, sizeof(double), &m->xyz));
    for (int64_t v = 0; v < m->nv; v++) {
      double ref;
      I2M_CHECK(rd_f64(r, &m->xyz[3 * v]) && rd_f64(r, &m->xyz[3 * v + 1]) &&
                    rd_f64(r, &m->xyz[3 * v + 2]) && rd_f64(r, &ref),
                I2M_ERR_INPUT, "%s: Vertices: truncated or malformed at vertex %lld of %lld",
                r->path, (long long)(v + 1), (long long)m->nv);
    }
  } else if (strcmp(kw, "Tetrahedra") == 0) {
    I2M_CALL(medit_elements(r, kw, 4, &m->nt, &m->tet, &m->tet_label));
  } else if (strcmp(kw, "Triangles") == 0) {
    I2M_CALL(medit_elements(r, kw, 3, &m->ntri, &m->tri, tri_ref));
    m->has_tri = 1;
  } else if (strcmp(kw, "End") == 0) {
    *done = 1;
  } else if (strcmp(kw, "Identifier") == 0 || strcmp(kw, "Geometry") == 0) {
    rd_line_end(r);
    rd_line_end(r);
  } else if (medit_skip_per(kw) > 0) {
    I2M_CALL(medit_skip(r, kw, medit_skip_per(kw)));
  } else {
    return I2M_ERROR(I2M_ERR_INPUT, "%s: unknown Medit keyword '%.40s'", r->path, kw);
  }
  return I2M_OK;
}

static i2m_err_t read_medit(rd_t *r, ck_mesh_t *m)
{
  medit_map_t map = {0};
  int64_t *tri_ref = NULL, *lut = NULL;
  int dim = 0, done = 0;
  i2m_err_t err = I2M_OK;
  char kw[64];
  while (!done) {
    rd_ws(r);
    if (r->p >= r->end) break;
    if (*r->p == '#') {
      I2M_CALL_GOTO(err, out, medit_comment(r, &map));
      continue;
    }
    rd_word(r, kw, sizeof kw);
    I2M_CALL_GOTO(err, out, medit_keyword(r, kw, m, &tri_ref, &dim, &done));
  }
  I2M_CHECK_GOTO(m->xyz != NULL || m->nv == 0, err, out, I2M_ERR_INPUT, "%s: no Vertices",
                 r->path);
  I2M_CHECK_GOTO(dim == 3, err, out, I2M_ERR_INPUT, "%s: not a Medit mesh (no Dimension 3)",
                 r->path);
  /* End is the last thing written: without it the file was cut, maybe between sections */
  I2M_CHECK_GOTO(done, err, out, I2M_ERR_INPUT, "%s: truncated file (no End keyword)", r->path);
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)m->ntri * 2, sizeof(int64_t), &m->tri_label));
  m->tri_labels_known = 1;
  int64_t maxref = 0;
  for (int64_t k = 0; k < map.n; k++)
    if (map.ref[k] > maxref && map.ref[k] <= ((int64_t)1 << 24)) maxref = map.ref[k];
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)maxref + 1, sizeof *lut, &lut));
  for (int64_t k = 0; k <= maxref; k++) lut[k] = -1;
  for (int64_t k = 0; k < map.n; k++)
    if (map.ref[k] >= 0 && map.ref[k] <= maxref) lut[map.ref[k]] = k;
  for (int64_t i = 0; i < m->ntri; i++) {
    int64_t k = tri_ref[i] >= 0 && tri_ref[i] <= maxref ? lut[tri_ref[i]] : -1;
    if (k < 0) {
      m->tri_labels_known = 0;
      m->tri_label[2 * i] = m->tri_label[2 * i + 1] = -1;
    } else {
      m->tri_label[2 * i] = map.a[k];
      m->tri_label[2 * i + 1] = map.b[k];
    }
  }
out:
  i2m_free(&map.ref);
  i2m_free(&map.a);
  i2m_free(&map.b);
  i2m_free(&tri_ref);
  i2m_free(&lut);
  return err;
}

/* ===================================== VTU ===================================== */

enum { VTU_SEC_POINTS, VTU_SEC_CELLS, VTU_SEC_CELLDATA, VTU_SEC_POINTDATA, VTU_SEC_OTHER };

typedef struct {
  const char *tag, *tag_end; /* "<DataArray" and its closing '>' */
  int section;
  char type[16], name[64], format[16];
  int64_t offset, ncomp;
} vtu_da_t;

typedef struct {
  const char *buf, *end, *path;
  const char *app;  /* first byte after the '_' of the appended data, or NULL */
  const char *app_end; /* the closing </AppendedData> tag: the appended arrays end before it */
  int hsize;        /* 4 or 8 */
  int swap;
  int zlib;         /* compressor="vtkZLibDataCompressor" */
  int app_base64;   /* <AppendedData encoding="base64">: offsets count base64 characters */
  int64_t max_values; /* no array of this file can hold more values (from the file's size) */
  ck_progress_t *pr;  /* or NULL: arrays read, as a share of the file's bytes */
} vtu_t;

/* deflate expands at most 1032 times: a compressed file holds at most that many bytes for
 * each of its own */
#define ZLIB_MAX_RATIO 1032

static int get_attr(const char *tag, const char *tag_end, const char *name, char *out, size_t size)
{
  char key[40];
  snprintf(key, sizeof key, " %s=\"", name);
  const char *a = find_str(tag, tag_end, key);
  if (!a) {
    snprintf(key, sizeof key, "\n%s=\"", name);
    a = find_str(tag, tag_end, key);
  }
  if (!a) return 0;
  a += strlen(key);
  size_t n = 0;
  while (a < tag_end && *a != '"') {
    if (n + 1 < size) out[n++] = *a;
    a++;
  }
  out[n] = '\0';
  return 1;
}

static int vtu_type_size(const char *t)
{
  static const char *names[] = {"Int8",   "UInt8",  "Int16", "UInt16",  "Int32",
                                "UInt32", "Int64",  "UInt64", "Float32", "Float64"};
  static const int sizes[] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  for (int i = 0; i < 10; i++)
    if (strcmp(t, names[i]) == 0) return sizes[i];
  return 0;
}

/* Value i of raw array data of the given type, as a double and as an int64. */
static void vtu_value(const char *t, const unsigned char *p, int swap, double *d, int64_t *v)
{
  unsigned char b[8];
  int n = vtu_type_size(t);
  for (int i = 0; i < n; i++) b[i] = swap ? p[n - 1 - i] : p[i];
  union {
    int8_t i8; uint8_t u8; int16_t i16; uint16_t u16; int32_t i32; uint32_t u32;
    int64_t i64; uint64_t u64; float f32; double f64;
  } u;
  memcpy(&u, b, (size_t)n);
  if (t[0] == 'F') {
    *d = n == 4 ? (double)u.f32 : u.f64;
    *v = *d > -9.0e18 && *d < 9.0e18 ? (int64_t)*d : INT64_MIN; /* NaN too */
    return;
  }
  int sgn = t[0] == 'I';
  switch (n) {
  case 1: *v = sgn ? u.i8 : u.u8; break;
  case 2: *v = sgn ? u.i16 : u.u16; break;
  case 4: *v = sgn ? u.i32 : (int64_t)u.u32; break;
  default: *v = sgn ? u.i64 : (int64_t)u.u64; break;
  }
  *d = (double)*v;
}

static int b64(int c)
{
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

/* Decodes base64 text [p, end) into *out (owned); *n bytes.  '=' padding ends a chunk (VTK
 * encodes an array's header apart from its data): the bits left over are dropped. */
static i2m_err_t b64_decode(const char *p, const char *end, unsigned char **out, size_t *n)
{
  I2M_CALL(i2m_malloc((size_t)(end - p) / 4 * 3 + 4, 1, out));
  uint32_t acc = 0;
  int bits = 0;
  *n = 0;
  for (; p < end; p++) {
    if (*p == '=') {
      acc = 0;
      bits = 0;
      continue;
    }
    int c = b64((unsigned char)*p);
    if (c < 0) continue; /* whitespace */
    acc = (acc << 6) | (uint32_t)c;
    bits += 6;
    if (bits >= 8) {
      bits -= 8;
      (*out)[(*n)++] = (unsigned char)(acc >> bits);
    }
  }
  return I2M_OK;
}

/* An unsigned header value (UInt32 or UInt64, the file's byte order) at p. */
static uint64_t vtu_header_value(const vtu_t *x, const unsigned char *p)
{
  uint64_t v = 0;
  for (int i = 0; i < x->hsize; i++) v |= (uint64_t)p[x->swap ? x->hsize - 1 - i : i] << (8 * i);
  return v;
}

/* Checks a raw array's header (its byte count) at data (avail bytes): want bytes follow. */
static i2m_err_t vtu_raw_payload(const vtu_t *x, const vtu_da_t *da, const unsigned char *data, size_t avail,
                                 uint64_t want, const unsigned char **payload)
{
  I2M_CHECK(avail >= (size_t)x->hsize, I2M_ERR_INPUT, "%s: DataArray %s: truncated", x->path, da->name);
  const uint64_t nbytes = vtu_header_value(x, data);
  I2M_CHECK(nbytes == want, I2M_ERR_INPUT, "%s: DataArray %s: %llu bytes where %llu are needed (%s)", x->path,
            da->name, (unsigned long long)nbytes, (unsigned long long)want, da->type);
  I2M_CHECK(avail - (size_t)x->hsize >= nbytes, I2M_ERR_INPUT,
            "%s: DataArray %s: truncated (%llu bytes announced, only %zu there)", x->path, da->name,
            (unsigned long long)nbytes, avail - (size_t)x->hsize);
  *payload = data + x->hsize;
  return I2M_OK;
}

/* Checks a compressed array's header [blocks, block size, last partial block size or 0,
 * compressed sizes] at data (avail bytes) against the want bytes it must inflate to. */
static i2m_err_t vtu_zlib_header(const vtu_t *x, const vtu_da_t *da, const unsigned char *data, size_t avail,
                                 uint64_t want, uint64_t h[3])
{
  const size_t hs = (size_t)x->hsize;
  I2M_CHECK(avail >= 3 * hs, I2M_ERR_INPUT, "%s: DataArray %s: truncated compression header", x->path, da->name);
  for (int i = 0; i < 3; i++) h[i] = vtu_header_value(x, data + i * hs);
  I2M_CHECK(h[0] <= (avail - 3 * hs) / hs, I2M_ERR_INPUT,
            "%s: DataArray %s: %llu compressed blocks announced, the file is too short for their sizes", x->path,
            da->name, (unsigned long long)h[0]);
  const uint64_t last = h[2] ? h[2] : h[1]; /* (0: the last block is whole) */
  const int fits = h[0] == 0 ? want == 0
                             : h[1] > 0 && h[2] <= h[1] && h[1] <= ((uLong)-1) && h[0] - 1 <= want / h[1] &&
                                   (h[0] - 1) * h[1] + last == want;
  I2M_CHECK(fits, I2M_ERR_INPUT,
            "%s: DataArray %s: compression header of %llu blocks of %llu bytes (last %llu) where %llu bytes are "
            "needed (%s)", x->path, da->name, (unsigned long long)h[0], (unsigned long long)h[1],
            (unsigned long long)h[2], (unsigned long long)want, da->type);
  return I2M_OK;
}

/* Inflates a compressed array at data (avail bytes) into *out (owned), want bytes. */
static i2m_err_t vtu_inflate(const vtu_t *x, const vtu_da_t *da, const unsigned char *data, size_t avail,
                             uint64_t want, unsigned char **out)
{
  uint64_t h[3];
  I2M_CALL(vtu_zlib_header(x, da, data, avail, want, h));
  const size_t hs = (size_t)x->hsize;
  const unsigned char *sizes = data + 3 * hs, *blk = sizes + h[0] * hs;
  size_t left = avail - (3 + h[0]) * hs;
  I2M_CALL(i2m_malloc(want ? want : 1, 1, out));
  for (uint64_t b = 0; b < h[0]; b++) {
    const uint64_t c = vtu_header_value(x, sizes + b * hs), u = b + 1 < h[0] || !h[2] ? h[1] : h[2];
    I2M_CHECK(c <= left, I2M_ERR_INPUT, "%s: DataArray %s: compressed block %llu of %llu is truncated", x->path,
              da->name, (unsigned long long)b, (unsigned long long)h[0]);
    uLongf got = (uLongf)u;
    const int rc = uncompress(*out + b * h[1], &got, blk, (uLong)c);
    I2M_CHECK(rc == Z_OK && got == u, I2M_ERR_INPUT,
              "%s: DataArray %s: compressed block %llu of %llu does not inflate to %llu bytes (%s)", x->path,
              da->name, (unsigned long long)b, (unsigned long long)h[0], (unsigned long long)u,
              rc == Z_OK ? "short" : zError(rc));
    blk += c;
    left -= (size_t)c;
  }
  return I2M_OK;
}

/* Decodes an appended base64 array (VTK's default encoding): from its offset, enough base64
 * characters for hbytes of header then dbytes of data, whether the two were encoded apart
 * (VTK) or together; the rest of the appended data at most.  *out (owned) replaces the last. */
static i2m_err_t b64_appended(const vtu_t *x, const vtu_da_t *da, uint64_t hbytes, uint64_t dbytes,
                              unsigned char **out, size_t *n)
{
  const char *p = x->app + da->offset;
  const uint64_t left = (uint64_t)(x->app_end - p), hchars = (hbytes + 2) / 3 * 4;
  const uint64_t chars = dbytes > left ? left : hchars + (dbytes + 2) / 3 * 4;
  i2m_free(out);
  return b64_decode(p, chars < left ? p + chars : x->app_end, out, n);
}

/* The header and data of an appended base64 array, decoded into *tmp: the header says how
 * much data follows (a byte count, or the compressed block sizes). */
static i2m_err_t vtu_appended_b64(const vtu_t *x, const vtu_da_t *da, unsigned char **tmp, size_t *avail)
{
  const uint64_t hs = (uint64_t)x->hsize;
  uint64_t hbytes = x->zlib ? 3 * hs : hs, dbytes = 0;
  I2M_CALL(b64_appended(x, da, hbytes, 0, tmp, avail));
  I2M_CHECK(*avail >= hbytes, I2M_ERR_INPUT, "%s: DataArray %s: truncated", x->path, da->name);
  if (x->zlib) {
    const uint64_t nb = vtu_header_value(x, *tmp);
    I2M_CHECK(nb <= (uint64_t)(x->app_end - x->app) / hs, I2M_ERR_INPUT,
              "%s: DataArray %s: %llu compressed blocks announced, the file is too short for their sizes", x->path,
              da->name, (unsigned long long)nb);
    hbytes += nb * hs;
    I2M_CALL(b64_appended(x, da, hbytes, 0, tmp, avail));
    I2M_CHECK(*avail >= hbytes, I2M_ERR_INPUT, "%s: DataArray %s: truncated", x->path, da->name);
    for (uint64_t b = 0; b < nb && dbytes <= (uint64_t)(x->app_end - x->app); b++)
      dbytes += vtu_header_value(x, *tmp + (3 + b) * hs);
  } else {
    dbytes = vtu_header_value(x, *tmp);
  }
  return b64_appended(x, da, hbytes, dbytes, tmp, avail);
}

/* The bytes of a binary array (appended raw, or base64 decoded into *tmp). */
static i2m_err_t vtu_binary_source(const vtu_t *x, const vtu_da_t *da, unsigned char **tmp,
                                   const unsigned char **data, size_t *avail)
{
  if (strcmp(da->format, "appended") == 0) {
    I2M_CHECK(x->app, I2M_ERR_INPUT, "%s: DataArray %s is appended but there is no AppendedData",
              x->path, da->name);
    I2M_CHECK(da->offset >= 0 && da->offset <= x->app_end - x->app, I2M_ERR_INPUT,
              "%s: DataArray %s: offset %lld beyond the end of the appended data", x->path,
              da->name, (long long)da->offset);
    if (x->app_base64) {
      I2M_CALL(vtu_appended_b64(x, da, tmp, avail));
      *data = *tmp;
      return I2M_OK;
    }
    *data = (const unsigned char *)x->app + da->offset;
    *avail = (size_t)((const unsigned char *)x->app_end - *data);
    return I2M_OK;
  }
  I2M_CHECK(strcmp(da->format, "binary") == 0, I2M_ERR_UNSUPPORTED,
            "%s: DataArray %s: format '%s' not supported", x->path, da->name, da->format);
  const char *stop = find_str(da->tag_end, x->end, "</DataArray>");
  I2M_CHECK(stop, I2M_ERR_INPUT, "%s: DataArray %s is not closed", x->path, da->name);
  I2M_CALL(b64_decode(da->tag_end + 1, stop, tmp, avail));
  *data = *tmp;
  return I2M_OK;
}

/* Reads count values of inline ascii array da into d (doubles) or v (int64). */
static i2m_err_t vtu_ascii_array(const vtu_t *x, const vtu_da_t *da, int64_t count, double *d, int64_t *v)
{
  rd_t r = {da->tag_end + 1, x->end, x->path, 0, NULL, NULL, 0};
  const char *stop = find_str(r.p, x->end, "</DataArray>");
  if (stop) r.end = stop;
  for (int64_t i = 0; i < count; i++) {
    double dd = 0;
    int64_t vv = 0;
    int ok = da->type[0] == 'F' ? rd_f64(&r, &dd) : rd_i64(&r, &vv);
    I2M_CHECK(ok, I2M_ERR_INPUT, "%s: DataArray %s: %lld values expected, fewer found",
              x->path, da->name, (long long)count);
    if (da->type[0] == 'F')
      vv = dd > -9.0e18 && dd < 9.0e18 ? (int64_t)dd : INT64_MIN;
    else
      dd = (double)vv;
    if (d) d[i] = dd;
    if (v) v[i] = vv;
  }
  return I2M_OK;
}

/* Reads count values of array da into d (doubles) or v (int64), whichever is not NULL. */
static i2m_err_t vtu_array(const vtu_t *x, const vtu_da_t *da, int64_t count, double *d, int64_t *v)
{
  const int ts = vtu_type_size(da->type);
  I2M_CHECK(ts > 0, I2M_ERR_INPUT, "%s: DataArray %s has unknown type '%s'", x->path, da->name,
            da->type);
  if (strcmp(da->format, "ascii") == 0) return vtu_ascii_array(x, da, count, d, v);
  unsigned char *tmp = NULL, *inflated = NULL;
  const unsigned char *data = NULL, *payload = NULL;
  size_t avail = 0;
  const uint64_t want = (uint64_t)count * (uint64_t)ts;
  i2m_err_t err = vtu_binary_source(x, da, &tmp, &data, &avail);
  if (err == I2M_OK && x->zlib) {
    err = vtu_inflate(x, da, data, avail, want, &inflated);
    payload = inflated;
  } else if (err == I2M_OK) {
    err = vtu_raw_payload(x, da, data, avail, want, &payload);
  }
  for (int64_t i = 0; err == I2M_OK && i < count; i++) {
    double dd;
    int64_t vv;
    vtu_value(da->type, payload + i * ts, x->swap, &dd, &vv);
    if (d) d[i] = dd;
    if (v) v[i] = vv;
  }
  /* the progress line: how far into the file this array lay (arrays are read out of order) */
  const char *at = (const char *)data;
  if (err == I2M_OK && x->pr && at >= x->buf && at < x->end && at - x->buf > atomic_load(&x->pr->done))
    ck_progress_to(x->pr, at - x->buf);
  i2m_free(&tmp);
  i2m_free(&inflated);
  return err;
}

/* Collects the DataArray tags of the XML part (before the appended data). */
static i2m_err_t vtu_scan(vtu_t *x, const char *xml_end, vtu_da_t *das, int *nda, int max)
{
  const char *p = x->buf;
  *nda = 0;
  while ((p = find_str(p, xml_end, "<DataArray")) != NULL) {
    I2M_CHECK(*nda < max, I2M_ERR_UNSUPPORTED, "%s: too many DataArrays", x->path);
    vtu_da_t *d = &das[(*nda)++];
    memset(d, 0, sizeof *d);
    d->tag = p;
    d->tag_end = memchr(p, '>', (size_t)(x->end - p));
    I2M_CHECK(d->tag_end, I2M_ERR_INPUT, "%s: unterminated DataArray tag", x->path);
    const char *sec[3] = {"<Points", "<Cells", "<CellData"};
    const char *best = NULL;
    d->section = VTU_SEC_OTHER;
    for (int s = 0; s < 3; s++) {
      const char *q = x->buf, *last = NULL;
      while ((q = find_str(q, p, sec[s])) != NULL) last = q++;
      if (last && (!best || last > best)) {
        best = last;
        d->section = s;
      }
    }
    const char *pd = x->buf, *lastpd = NULL;
    while ((pd = find_str(pd, p, "<PointData")) != NULL) lastpd = pd++;
    if (lastpd && (!best || lastpd > best)) d->section = VTU_SEC_POINTDATA;
    char buf[32];
    get_attr(p, d->tag_end, "type", d->type, sizeof d->type);
    get_attr(p, d->tag_end, "Name", d->name, sizeof d->name);
    if (!get_attr(p, d->tag_end, "format", d->format, sizeof d->format))
      strcpy(d->format, "ascii");
    d->offset = get_attr(p, d->tag_end, "offset", buf, sizeof buf) ? strtoll(buf, NULL, 10) : 0;
    d->ncomp = get_attr(p, d->tag_end, "NumberOfComponents", buf, sizeof buf)
                   ? strtoll(buf, NULL, 10) : 1;
    p = d->tag_end;
  }
  return I2M_OK;
}

static const vtu_da_t *vtu_find(const vtu_da_t *das, int nda, int section, const char *name)
{
  for (int i = 0; i < nda; i++)
    if (das[i].section == section && (!name || strcmp(das[i].name, name) == 0)) return &das[i];
  return NULL;
}

static i2m_err_t vtu_header(vtu_t *x, const char **xml_end, int64_t *np, int64_t *nc)
{
  char buf[64];
  const char *f = find_str(x->buf, x->end, "<VTKFile");
  I2M_CHECK(f, I2M_ERR_INPUT, "%s: not a VTK XML file (no <VTKFile>)", x->path);
  const char *fe = memchr(f, '>', (size_t)(x->end - f));
  I2M_CHECK(fe, I2M_ERR_INPUT, "%s: truncated VTKFile tag", x->path);
  I2M_CHECK(get_attr(f, fe, "type", buf, sizeof buf) && strcmp(buf, "UnstructuredGrid") == 0,
            I2M_ERR_UNSUPPORTED, "%s: VTK file type is not UnstructuredGrid", x->path);
  if (get_attr(f, fe, "compressor", buf, sizeof buf) && buf[0]) {
    I2M_CHECK(strcmp(buf, "vtkZLibDataCompressor") == 0, I2M_ERR_UNSUPPORTED,
              "%s: compressor %s is not supported (vtkZLibDataCompressor only)", x->path, buf);
    x->zlib = 1;
  }
  x->swap = get_attr(f, fe, "byte_order", buf, sizeof buf) && strcmp(buf, "BigEndian") == 0;
  x->hsize = get_attr(f, fe, "header_type", buf, sizeof buf) && strcmp(buf, "UInt64") == 0 ? 8 : 4;
  const char *ad = find_str(fe, x->end, "<AppendedData");
  *xml_end = ad ? ad : x->end;
  if (ad) {
    const char *ae = memchr(ad, '>', (size_t)(x->end - ad));
    I2M_CHECK(ae, I2M_ERR_INPUT, "%s: truncated AppendedData tag", x->path);
    if (get_attr(ad, ae, "encoding", buf, sizeof buf)) {
      I2M_CHECK(strcmp(buf, "raw") == 0 || strcmp(buf, "base64") == 0, I2M_ERR_UNSUPPORTED,
                "%s: AppendedData encoding '%s' not supported (raw or base64)", x->path, buf);
      x->app_base64 = strcmp(buf, "base64") == 0;
    }
    const char *u = memchr(ae, '_', (size_t)(x->end - ae));
    I2M_CHECK(u, I2M_ERR_INPUT, "%s: AppendedData without '_'", x->path);
    x->app = u + 1;
    /* the last one: the raw bytes before it may hold the same text by chance */
    x->app_end = find_last_str(x->app, x->end, "</AppendedData>");
    I2M_CHECK(x->app_end, I2M_ERR_INPUT, "%s: truncated file (no </AppendedData>)", x->path);
  }
  /* the closing tag is the last thing written: without it the file was cut */
  const char *tail = x->end - (x->end - x->buf > 64 ? 64 : x->end - x->buf);
  I2M_CHECK(find_str(tail, x->end, "</VTKFile>"), I2M_ERR_INPUT,
            "%s: truncated file (no </VTKFile> at the end)", x->path);
  const char *pc = find_str(x->buf, *xml_end, "<Piece");
  I2M_CHECK(pc, I2M_ERR_INPUT, "%s: no <Piece>", x->path);
  const char *pe = memchr(pc, '>', (size_t)(x->end - pc));
  I2M_CHECK(pe && find_str(pe, *xml_end, "<Piece") == NULL, I2M_ERR_UNSUPPORTED,
            "%s: several Pieces are not supported", x->path);
  I2M_CHECK(get_attr(pc, pe, "NumberOfPoints", buf, sizeof buf), I2M_ERR_INPUT,
            "%s: Piece without NumberOfPoints", x->path);
  *np = strtoll(buf, NULL, 10);
  I2M_CHECK(get_attr(pc, pe, "NumberOfCells", buf, sizeof buf), I2M_ERR_INPUT,
            "%s: Piece without NumberOfCells", x->path);
  *nc = strtoll(buf, NULL, 10);
  const int64_t lim = (int64_t)(x->end - x->buf);
  x->max_values = x->zlib ? lim * ZLIB_MAX_RATIO : lim;
  I2M_CHECK(*np >= 0 && *nc >= 0 && *np <= x->max_values && *nc <= x->max_values, I2M_ERR_INPUT,
            "%s: NumberOfPoints %lld / NumberOfCells %lld do not fit a %lld-byte%s file", x->path,
            (long long)*np, (long long)*nc, (long long)lim, x->zlib ? " compressed" : "");
  return I2M_OK;
}

/* The point data "GlobalNodeId" (one integer per point), when the file has it. */
static i2m_err_t vtu_global_ids(const vtu_t *x, const vtu_da_t *das, int nda, int64_t np,
                                ck_mesh_t *m)
{
  const vtu_da_t *dg = vtu_find(das, nda, VTU_SEC_POINTDATA, "GlobalNodeId");
  if (!dg) return I2M_OK;
  I2M_CHECK(dg->ncomp == 1 && dg->type[0] != 'F', I2M_ERR_INPUT,
            "%s: GlobalNodeId must be one integer per point (found %lld x %s)", x->path,
            (long long)dg->ncomp, dg->type);
  I2M_CALL(i2m_malloc((size_t)np, sizeof *m->gid, &m->gid));
  I2M_CALL(vtu_array(x, dg, np, NULL, m->gid));
  m->has_gid = 1;
  return I2M_OK;
}

static i2m_err_t read_vtu(const char *buf, size_t len, const char *path, ck_mesh_t *m, ck_progress_t *pr)
{
  vtu_t x = {buf, buf + len, path, NULL, NULL, 4, 0, 0, 0, 0, pr};
  vtu_da_t das[64];
  int nda = 0;
  const char *xml_end = NULL;
  int64_t np = 0, nc = 0, *conn = NULL, *offs = NULL, *types = NULL, *mat = NULL;
  i2m_err_t err = I2M_OK;
  I2M_CALL(vtu_header(&x, &xml_end, &np, &nc));
  I2M_CALL(vtu_scan(&x, xml_end, das, &nda, 64));
  const vtu_da_t *dp = vtu_find(das, nda, VTU_SEC_POINTS, NULL);
  const vtu_da_t *dc = vtu_find(das, nda, VTU_SEC_CELLS, "connectivity");
  const vtu_da_t *doff = vtu_find(das, nda, VTU_SEC_CELLS, "offsets");
  const vtu_da_t *dt = vtu_find(das, nda, VTU_SEC_CELLS, "types");
  const vtu_da_t *dm = vtu_find(das, nda, VTU_SEC_CELLDATA, "material");
  if (!dm) dm = vtu_find(das, nda, VTU_SEC_CELLDATA, NULL);
  I2M_CHECK(dp && dc && doff && dt, I2M_ERR_INPUT,
            "%s: missing Points or Cells arrays (connectivity, offsets, types)", path);
  I2M_CHECK(dp->ncomp == 3, I2M_ERR_INPUT, "%s: Points have %lld components", path,
            (long long)dp->ncomp);
  m->nv = np;
  I2M_CALL(i2m_malloc((size_t)np * 3, sizeof(double), &m->xyz));
  I2M_CALL(vtu_array(&x, dp, 3 * np, m->xyz, NULL));
  I2M_CALL(vtu_global_ids(&x, das, nda, np, m));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nc, sizeof *offs, &offs));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nc, sizeof *types, &types));
  I2M_CALL_GOTO(err, out, vtu_array(&x, doff, nc, NULL, offs));
  I2M_CALL_GOTO(err, out, vtu_array(&x, dt, nc, NULL, types));
  int64_t nconn = nc ? offs[nc - 1] : 0;
  I2M_CHECK_GOTO(nconn >= 0 && nconn <= x.max_values, err, out, I2M_ERR_INPUT,
                 "%s: bad last cell offset %lld", path, (long long)nconn);
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nconn, sizeof *conn, &conn));
  I2M_CALL_GOTO(err, out, vtu_array(&x, dc, nconn, NULL, conn));
  if (dm) {
    I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nc, sizeof *mat, &mat));
    I2M_CALL_GOTO(err, out, vtu_array(&x, dm, nc, NULL, mat));
  }
  int64_t nt = 0;
  for (int64_t c = 0; c < nc; c++) nt += types[c] == 10;
  m->nt = nt;
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nt * 4, sizeof(int64_t), &m->tet));
  I2M_CALL_GOTO(err, out, i2m_malloc((size_t)nt, sizeof(int64_t), &m->tet_label));
  nt = 0;
  for (int64_t c = 0; c < nc; c++) {
    int64_t s = c ? offs[c - 1] : 0;
    I2M_CHECK_GOTO(s >= 0 && offs[c] >= s && offs[c] <= nconn, err, out, I2M_ERR_INPUT,
                   "%s: cell offsets are not increasing at cell %lld", path, (long long)c);
    if (types[c] != 10) {
      m->ignored_cells++;
      continue;
    }
    I2M_CHECK_GOTO(offs[c] - s == 4, err, out, I2M_ERR_INPUT,
                   "%s: tetrahedron %lld has %lld vertices", path, (long long)c,
                   (long long)(offs[c] - s));
    for (int j = 0; j < 4; j++) m->tet[4 * nt + j] = conn[s + j];
    m->tet_label[nt++] = mat ? mat[c] : 1;
  }
out:
  i2m_free(&conn);
  i2m_free(&offs);
  i2m_free(&types);
  i2m_free(&mat);
  return err;
}

/* ===================================== Gmsh ==================================== */

typedef struct {
  rd_t r;
  int binary;
  int v22;       /* MSH 2.2 (else 4.1) */
  /* physical names: tag -> pair (dim 2 "interface_A_B") */
  int64_t nphys;
  int64_t *phys; /* owned: [nphys][4] dim, tag, a, b (a = b = -1: not an interface name) */
  /* entity (dim, tag) -> first physical tag (0 = none) */
  int64_t nent;
  int64_t *ent;  /* owned: [nent][3] dim, tag, physical */
  int64_t *node_map; /* owned: [max_tag+1] node tag -> index, -1 */
  int64_t max_tag;
} gm_t;

static int g_size(gm_t *g, int64_t *v)
{
  if (!g->binary) return rd_i64(&g->r, v) && *v >= 0;
  uint64_t u;
  if (!rd_bin(&g->r, &u, 8)) return 0;
  *v = (int64_t)u;
  return *v >= 0;
}

static int g_int(gm_t *g, int64_t *v)
{
  if (!g->binary) return rd_i64(&g->r, v);
  int32_t i;
  if (!rd_bin(&g->r, &i, 4)) return 0;
  *v = i;
  return 1;
}

static int g_dbl(gm_t *g, double *v)
{
  if (!g->binary) return rd_f64(&g->r, v);
  return rd_bin(&g->r, v, 8);
}

#define G_NEED(g, cond, sec)                                                                 \
  I2M_CHECK(cond, I2M_ERR_INPUT, "%s: $%s: truncated or malformed", (g)->r.path, sec)

static i2m_err_t gm_physical_names(gm_t *g, ck_mesh_t *m)
{
  (void)m; /* (the signature of every section reader) */
  int64_t n;
  G_NEED(g, rd_i64(&g->r, &n) && count_fits(&g->r, n, 6), "PhysicalNames");
  I2M_CALL(i2m_malloc((size_t)n * 4, sizeof(int64_t), &g->phys));
  g->nphys = n;
  for (int64_t i = 0; i < n; i++) {
    int64_t *p = g->phys + 4 * i;
    char name[256];
    G_NEED(g, rd_i64(&g->r, &p[0]) && rd_i64(&g->r, &p[1]), "PhysicalNames");
    rd_ws(&g->r);
    G_NEED(g, g->r.p < g->r.end && *g->r.p == '"', "PhysicalNames");
    const char *q = ++g->r.p;
    while (g->r.p < g->r.end && *g->r.p != '"') g->r.p++;
    G_NEED(g, g->r.p < g->r.end, "PhysicalNames");
    size_t len = (size_t)(g->r.p - q) < sizeof name - 1 ? (size_t)(g->r.p - q) : sizeof name - 1;
    memcpy(name, q, len);
    name[len] = '\0';
    g->r.p++;
    long long a, b;
    char tail;
    p[2] = p[3] = -1;
    if (sscanf(name, "interface_%lld_%lld%c", &a, &b, &tail) == 2) {
      p[2] = a < b ? a : b;
      p[3] = a < b ? b : a;
    }
  }
  return I2M_OK;
}

static i2m_err_t gm_entities(gm_t *g, ck_mesh_t *m)
{
  (void)m; /* (the signature of every section reader) */
  int64_t cnt[4], total = 0;
  for (int d = 0; d < 4; d++) {
    G_NEED(g, g_size(g, &cnt[d]) && count_fits(&g->r, cnt[d], 8), "Entities");
    total += cnt[d];
  }
  I2M_CALL(i2m_malloc((size_t)total * 3, sizeof(int64_t), &g->ent));
  for (int d = 0; d < 4; d++)
    for (int64_t e = 0; e < cnt[d]; e++) {
      int64_t tag, nph, ph = 0, x, nb;
      double bb;
      G_NEED(g, g_int(g, &tag), "Entities");
      for (int k = 0; k < (d == 0 ? 3 : 6); k++) G_NEED(g, g_dbl(g, &bb), "Entities");
      G_NEED(g, g_size(g, &nph) && count_fits(&g->r, nph, 2), "Entities");
      for (int64_t k = 0; k < nph; k++) {
        G_NEED(g, g_int(g, &x), "Entities");
        if (k == 0) ph = x;
      }
      if (d > 0) {
        G_NEED(g, g_size(g, &nb) && count_fits(&g->r, nb, 2), "Entities");
        for (int64_t k = 0; k < nb; k++) G_NEED(g, g_int(g, &x), "Entities");
      }
      int64_t *p = g->ent + 3 * g->nent++;
      p[0] = d;
      p[1] = tag;
      p[2] = ph;
    }
  return I2M_OK;
}

/* The node tag -> index map of the tags tag[0 .. nn-1] (2.2: tags as found). */
static i2m_err_t gm_node_map(gm_t *g, const int64_t *tag, int64_t nn)
{
  int64_t maxtag = 0;
  for (int64_t i = 0; i < nn; i++) {
    I2M_CHECK(tag[i] >= 1, I2M_ERR_INPUT, "%s: node tag %lld is not positive", g->r.path, (long long)tag[i]);
    if (tag[i] > maxtag) maxtag = tag[i];
  }
  I2M_CHECK(maxtag <= 8 * nn + 1000000, I2M_ERR_UNSUPPORTED,
            "%s: node tags up to %lld for %lld nodes are too sparse", g->r.path, (long long)maxtag, (long long)nn);
  I2M_CALL(i2m_malloc((size_t)maxtag + 1, sizeof(int64_t), &g->node_map));
  g->max_tag = maxtag;
  for (int64_t t = 0; t <= maxtag; t++) g->node_map[t] = -1;
  for (int64_t i = 0; i < nn; i++) {
    I2M_CHECK(g->node_map[tag[i]] < 0, I2M_ERR_INPUT, "%s: node tag %lld appears twice", g->r.path,
              (long long)tag[i]);
    g->node_map[tag[i]] = i;
  }
  return I2M_OK;
}

/* MSH 2.2 $Nodes: the count (text), then each node's tag and coordinates (binary: int32 and
 * three doubles). */
static i2m_err_t gm_nodes_22(gm_t *g, ck_mesh_t *m)
{
  int64_t nn, *tag = NULL;
  G_NEED(g, rd_i64(&g->r, &nn) && count_fits(&g->r, nn, 8), "Nodes");
  if (g->binary) rd_line_end(&g->r);
  m->nv = nn;
  I2M_CALL(i2m_malloc((size_t)nn * 3 + 1, sizeof(double), &m->xyz));
  I2M_CALL(i2m_malloc((size_t)nn + 1, sizeof *tag, &tag));
  i2m_err_t err = I2M_OK;
  for (int64_t i = 0; i < nn && err == I2M_OK; i++) {
    int ok = g_int(g, &tag[i]);
    for (int a = 0; a < 3; a++) ok = ok && g_dbl(g, &m->xyz[3 * i + a]);
    if (!ok) err = I2M_ERROR(I2M_ERR_INPUT, "%s: $Nodes: truncated or malformed", g->r.path);
  }
  if (err == I2M_OK) err = gm_node_map(g, tag, nn);
  i2m_free(&tag);
  return err;
}

static i2m_err_t gm_nodes(gm_t *g, ck_mesh_t *m)
{
  if (g->v22) return gm_nodes_22(g, m);
  int64_t nblk, nn, mintag, maxtag, done = 0;
  G_NEED(g, g_size(g, &nblk) && g_size(g, &nn) && g_size(g, &mintag) && g_size(g, &maxtag),
         "Nodes");
  G_NEED(g, count_fits(&g->r, nn, 8) && count_fits(&g->r, nblk, 8), "Nodes");
  I2M_CHECK(maxtag <= 8 * nn + 1000000, I2M_ERR_UNSUPPORTED,
            "%s: node tags up to %lld for %lld nodes are too sparse", g->r.path,
            (long long)maxtag, (long long)nn);
  m->nv = nn;
  I2M_CALL(i2m_malloc((size_t)nn * 3, sizeof(double), &m->xyz));
  I2M_CALL(i2m_malloc((size_t)maxtag + 1, sizeof(int64_t), &g->node_map));
  g->max_tag = maxtag;
  for (int64_t t = 0; t <= maxtag; t++) g->node_map[t] = -1;
  for (int64_t b = 0; b < nblk; b++) {
    int64_t dim, tag, par, n;
    G_NEED(g, g_int(g, &dim) && g_int(g, &tag) && g_int(g, &par) && g_size(g, &n), "Nodes");
    I2M_CHECK(par == 0, I2M_ERR_UNSUPPORTED, "%s: parametric nodes are not supported", g->r.path);
    I2M_CHECK(n <= nn - done, I2M_ERR_INPUT, "%s: $Nodes: more nodes in blocks than announced",
              g->r.path);
    for (int64_t i = 0; i < n; i++) {
      int64_t t;
      G_NEED(g, g_size(g, &t), "Nodes");
      I2M_CHECK(t >= 1 && t <= maxtag, I2M_ERR_INPUT, "%s: node tag %lld out of [1, %lld]",
                g->r.path, (long long)t, (long long)maxtag);
      I2M_CHECK(g->node_map[t] < 0, I2M_ERR_INPUT, "%s: node tag %lld appears twice", g->r.path,
                (long long)t);
      g->node_map[t] = done + i;
    }
    for (int64_t i = 0; i < 3 * n; i++) G_NEED(g, g_dbl(g, &m->xyz[3 * done + i]), "Nodes");
    done += n;
  }
  I2M_CHECK(done == nn, I2M_ERR_INPUT, "%s: $Nodes announces %lld nodes, blocks hold %lld",
            g->r.path, (long long)nn, (long long)done);
  return I2M_OK;
}

static int gm_nodes_per(int64_t type)
{
  switch (type) {
  case 15: return 1;
  case 1: return 2;
  case 2: return 3;
  case 3: return 4;
  case 4: return 4;
  case 5: return 8;
  case 6: return 6;
  case 7: return 5;
  case 8: return 3;
  case 9: return 6;
  case 11: return 10;
  default: return 0;
  }
}

static int64_t gm_entity_phys(const gm_t *g, int64_t dim, int64_t tag)
{
  for (int64_t e = 0; e < g->nent; e++)
    if (g->ent[3 * e] == dim && g->ent[3 * e + 1] == tag) return g->ent[3 * e + 2];
  return 0;
}

static int64_t gm_node(const gm_t *g, int64_t t)
{
  return t >= 1 && t <= g->max_tag ? g->node_map[t] : INT64_MAX;
}

/* The label pair of the triangles of physical group @p ph (a = c = -1: unknown). */
static void gm_pair_of(const gm_t *g, int64_t ph, int64_t *a, int64_t *c)
{
  *a = *c = -1;
  for (int64_t k = 0; k < g->nphys; k++)
    if (g->phys[4 * k] == 2 && g->phys[4 * k + 1] == ph) {
      *a = g->phys[4 * k + 2];
      *c = g->phys[4 * k + 3];
    }
}

/* Stores one element of @p type with node tags v[] in physical group ph (else entity tag). */
static void gm_store(const gm_t *g, ck_mesh_t *m, int64_t type, int64_t ph, int64_t tag, const int64_t *v)
{
  if (type == 4) {
    for (int j = 0; j < 4; j++) m->tet[4 * m->nt + j] = gm_node(g, v[j]);
    m->tet_label[m->nt++] = ph ? ph : tag;
  } else if (type == 2) {
    int64_t a, c;
    gm_pair_of(g, ph, &a, &c);
    if (a < 0) m->tri_labels_known = 0;
    for (int j = 0; j < 3; j++) m->tri[3 * m->ntri + j] = gm_node(g, v[j]);
    m->tri_label[2 * m->ntri] = a;
    m->tri_label[2 * m->ntri + 1] = c;
    m->ntri++;
  } else {
    m->ignored_cells++;
  }
}

static i2m_err_t gm_alloc_elements(gm_t *g, ck_mesh_t *m, int64_t ne)
{
  I2M_CHECK(g->node_map || ne == 0, I2M_ERR_INPUT, "%s: $Elements before $Nodes", g->r.path);
  I2M_CALL(i2m_malloc((size_t)ne * 4 + 1, sizeof(int64_t), &m->tet));
  I2M_CALL(i2m_malloc((size_t)ne + 1, sizeof(int64_t), &m->tet_label));
  I2M_CALL(i2m_malloc((size_t)ne * 3 + 1, sizeof(int64_t), &m->tri));
  I2M_CALL(i2m_malloc((size_t)ne * 2 + 1, sizeof(int64_t), &m->tri_label));
  m->tri_labels_known = 1;
  return I2M_OK;
}

/* One MSH 2.2 element after its tag: ASCII "type ntags tags... nodes...", binary the tags and
 * nodes of the block's type. */
static i2m_err_t gm_element_22(gm_t *g, ck_mesh_t *m, int64_t type, int64_t ntags)
{
  int64_t tags[2] = {0, 0}, x, v[10];
  int per = gm_nodes_per(type);
  I2M_CHECK(per > 0, I2M_ERR_UNSUPPORTED, "%s: element type %lld not supported", g->r.path, (long long)type);
  G_NEED(g, ntags >= 0 && count_fits(&g->r, ntags, 2), "Elements");
  for (int64_t k = 0; k < ntags; k++) {
    G_NEED(g, g_int(g, &x), "Elements");
    if (k < 2) tags[k] = x;
  }
  for (int j = 0; j < per; j++) G_NEED(g, g_int(g, &v[j]), "Elements");
  gm_store(g, m, type, tags[0], tags[1], v);
  return I2M_OK;
}

/* MSH 2.2 $Elements: the count (text), then ASCII lines "tag type ntags tags... nodes...", or
 * binary blocks: a header (type, count, ntags) and count elements (tag, tags, nodes). */
static i2m_err_t gm_elements_22(gm_t *g, ck_mesh_t *m)
{
  int64_t ne, id, type, ntags, n;
  G_NEED(g, rd_i64(&g->r, &ne) && count_fits(&g->r, ne, 8), "Elements");
  if (g->binary) rd_line_end(&g->r);
  I2M_CALL(gm_alloc_elements(g, m, ne));
  for (int64_t seen = 0; seen < ne;) {
    if (!g->binary) {
      G_NEED(g, g_int(g, &id) && g_int(g, &type) && g_int(g, &ntags), "Elements");
      I2M_CALL(gm_element_22(g, m, type, ntags));
      seen++;
      continue;
    }
    G_NEED(g, g_int(g, &type) && g_int(g, &n) && g_int(g, &ntags), "Elements");
    I2M_CHECK(n >= 0 && n <= ne - seen, I2M_ERR_INPUT, "%s: $Elements: more elements than announced", g->r.path);
    I2M_CHECK(n > 0, I2M_ERR_INPUT, "%s: $Elements: an empty block", g->r.path);
    for (int64_t i = 0; i < n; i++) {
      G_NEED(g, g_int(g, &id), "Elements");
      I2M_CALL(gm_element_22(g, m, type, ntags));
    }
    seen += n;
  }
  m->has_tri = m->ntri > 0;
  return I2M_OK;
}

static i2m_err_t gm_elements(gm_t *g, ck_mesh_t *m)
{
  if (g->v22) return gm_elements_22(g, m);
  int64_t nblk, ne, mn, mx;
  G_NEED(g, g_size(g, &nblk) && g_size(g, &ne) && g_size(g, &mn) && g_size(g, &mx), "Elements");
  G_NEED(g, count_fits(&g->r, ne, 8) && count_fits(&g->r, nblk, 8), "Elements");
  I2M_CALL(gm_alloc_elements(g, m, ne));
  int64_t seen = 0;
  for (int64_t b = 0; b < nblk; b++) {
    int64_t dim, tag, type, n, id;
    G_NEED(g, g_int(g, &dim) && g_int(g, &tag) && g_int(g, &type) && g_size(g, &n), "Elements");
    int per = gm_nodes_per(type);
    I2M_CHECK(per > 0, I2M_ERR_UNSUPPORTED, "%s: element type %lld not supported", g->r.path,
              (long long)type);
    I2M_CHECK(n <= ne - seen, I2M_ERR_INPUT, "%s: $Elements: more elements than announced",
              g->r.path);
    seen += n;
    const int64_t ph = gm_entity_phys(g, dim, tag);
    for (int64_t i = 0; i < n; i++) {
      int64_t v[10];
      G_NEED(g, g_size(g, &id), "Elements");
      for (int j = 0; j < per; j++) G_NEED(g, g_size(g, &v[j]), "Elements");
      gm_store(g, m, type, ph, tag, v);
    }
  }
  m->has_tri = m->ntri > 0;
  return I2M_OK;
}

static i2m_err_t gm_format(gm_t *g, ck_mesh_t *m)
{
  (void)m; /* (the signature of every section reader) */
  char ver[16];
  int64_t ft, ds;
  G_NEED(g, rd_word(&g->r, ver, sizeof ver) && rd_i64(&g->r, &ft) && rd_i64(&g->r, &ds),
         "MeshFormat");
  I2M_CHECK(strcmp(ver, "4.1") == 0 || strcmp(ver, "2.2") == 0, I2M_ERR_UNSUPPORTED,
            "%s: MSH version %s (only 4.1 and 2.2 are supported)", g->r.path, ver);
  g->v22 = strcmp(ver, "2.2") == 0;
  I2M_CHECK(ft == 0 || ft == 1, I2M_ERR_INPUT, "%s: bad MSH file type %lld", g->r.path, (long long)ft);
  g->binary = ft == 1;
  if (g->binary) {
    I2M_CHECK(ds == 8, I2M_ERR_UNSUPPORTED, "%s: binary MSH with %lld-byte size_t", g->r.path,
              (long long)ds);
    rd_line_end(&g->r);
    int32_t one;
    G_NEED(g, rd_bin(&g->r, &one, 4), "MeshFormat");
    if (one != 1) {
      g->r.swap = 1;
      I2M_CHECK(one == 0x01000000, I2M_ERR_INPUT, "%s: bad endianness mark", g->r.path);
    }
  }
  return I2M_OK;
}

/* The sections read, in the order Gmsh writes them, with their readers; others are skipped. */
static const struct {
  const char *name;
  i2m_err_t (*read)(gm_t *g, ck_mesh_t *m);
} GM_SECTIONS[] = {{"$MeshFormat", gm_format}, {"$PhysicalNames", gm_physical_names},
                   {"$Entities", gm_entities}, {"$Nodes", gm_nodes}, {"$Elements", gm_elements}};
enum { GM_NSECTIONS = sizeof GM_SECTIONS / sizeof GM_SECTIONS[0] };

static int gm_section_index(const char *sec)
{
  for (int i = 0; i < GM_NSECTIONS; i++)
    if (strcmp(sec, GM_SECTIONS[i].name) == 0) return i;
  return -1;
}

/* Reads section @p which of GM_SECTIONS (-1: skips an unknown one up to @p endw). */
static i2m_err_t gm_section(gm_t *g, int which, const char *sec, const char *endw, ck_mesh_t *m)
{
  if (which >= 0) return GM_SECTIONS[which].read(g, m);
  const char *e = find_str(g->r.p, g->r.end, endw);
  I2M_CHECK(e, I2M_ERR_INPUT, "%s: %s is not closed", g->r.path, sec);
  g->r.p = e;
  return I2M_OK;
}

static i2m_err_t read_gmsh(rd_t *r0, ck_mesh_t *m)
{
  gm_t g;
  memset(&g, 0, sizeof g);
  g.r = *r0;
  i2m_err_t err = I2M_OK;
  char sec[64], endw[80];
  int last = -1; /* index of the last section of GM_SECTIONS read */
  for (;;) {
    rd_ws(&g.r);
    if (g.r.p >= g.r.end) break;
    I2M_CHECK_GOTO(*g.r.p == '$', err, out, I2M_ERR_INPUT,
                   "%s: expected a $Section at byte %lld", g.r.path, (long long)(g.r.p - r0->p));
    rd_word(&g.r, sec, sizeof sec);
    rd_line_end(&g.r); /* binary data start right after the header line */
    int which = gm_section_index(sec);
    I2M_CHECK_GOTO(which == 0 || last >= 0, err, out, I2M_ERR_INPUT,
                   "%s: not a Gmsh file (no $MeshFormat)", g.r.path);
    /* each once (a second one would be read over the arrays of the first), in order */
    I2M_CHECK_GOTO(which < 0 || which != last, err, out, I2M_ERR_INPUT,
                   "%s: %s appears twice", g.r.path, sec);
    I2M_CHECK_GOTO(which < 0 || which > last, err, out, I2M_ERR_INPUT,
                   "%s: %s after %s (the sections must come in the order $MeshFormat "
                   "$PhysicalNames $Entities $Nodes $Elements)", g.r.path, sec, GM_SECTIONS[last].name);
    if (which >= 0) last = which;
    snprintf(endw, sizeof endw, "$End%s", sec + 1);
    I2M_CALL_GOTO(err, out, gm_section(&g, which, sec, endw, m));
    rd_word(&g.r, sec, sizeof sec);
    I2M_CHECK_GOTO(strcmp(sec, endw) == 0, err, out, I2M_ERR_INPUT,
                   "%s: expected %s, found '%.20s' (truncated or corrupt file)", g.r.path, endw, sec);
  }
  I2M_CHECK_GOTO(last == GM_NSECTIONS - 1, err, out, I2M_ERR_INPUT,
                 "%s: not a complete Gmsh mesh (no $MeshFormat or $Elements)", g.r.path);
out:
  i2m_free(&g.phys);
  i2m_free(&g.ent);
  i2m_free(&g.node_map);
  return err;
}

/* ===================================== PVTU ==================================== */

/* Piece file name: Source relative to the .pvtu's directory (an absolute one as it is). */
static i2m_err_t pvtu_piece_path(const char *pvtu, const char *src, char **out)
{
  const char *slash = strrchr(pvtu, '/');
  size_t d = src[0] == '/' || !slash ? 0 : (size_t)(slash - pvtu + 1), n = strlen(src);
  I2M_CALL(i2m_malloc(d + n + 1, 1, out));
  memcpy(*out, pvtu, d);
  memcpy(*out + d, src, n + 1);
  return I2M_OK;
}

static int count_str(const char *p, const char *end, const char *s)
{
  int n = 0;
  while ((p = find_str(p, end, s)) != NULL) {
    n++;
    p++;
  }
  return n;
}

/* The Source of every <Piece> tag of a PUnstructuredGrid file held in buf. */
static i2m_err_t pvtu_scan(const char *path, const char *buf, size_t len, char ***pieces, int *n)
{
  const char *end = buf + len, *f = find_str(buf, end, "<VTKFile");
  char type[32], src[4096];
  I2M_CHECK(f, I2M_ERR_INPUT, "%s: not a VTK XML file (no <VTKFile>)", path);
  const char *fe = memchr(f, '>', (size_t)(end - f));
  I2M_CHECK(fe && get_attr(f, fe, "type", type, sizeof type), I2M_ERR_INPUT,
            "%s: VTKFile tag without a type", path);
  I2M_CHECK(strcmp(type, "PUnstructuredGrid") == 0, I2M_ERR_UNSUPPORTED,
            "%s: VTK file type is %s, not PUnstructuredGrid", path, type);
  I2M_CHECK(find_str(fe, end, "</VTKFile>"), I2M_ERR_INPUT,
            "%s: truncated file (no </VTKFile>)", path);
  int count = count_str(fe, end, "<Piece");
  I2M_CHECK(count > 0, I2M_ERR_INPUT, "%s: no <Piece Source=...> in the file", path);
  I2M_CALL(i2m_calloc((size_t)count, sizeof **pieces, pieces));
  const char *p = fe;
  for (*n = 0; *n < count; (*n)++) {
    p = find_str(p, end, "<Piece");
    const char *pe = memchr(p, '>', (size_t)(end - p));
    I2M_CHECK(pe && get_attr(p, pe, "Source", src, sizeof src) && src[0], I2M_ERR_INPUT,
              "%s: <Piece> number %d has no Source", path, *n);
    I2M_CALL(pvtu_piece_path(path, src, &(*pieces)[*n]));
    p = pe;
  }
  return I2M_OK;
}

i2m_err_t ck_pvtu_pieces(const char *path, char ***pieces, int *npieces)
{
  char *buf = NULL;
  size_t len = 0;
  *pieces = NULL;
  *npieces = 0;
  I2M_CALL(read_file(path, &buf, &len));
  i2m_err_t err = pvtu_scan(path, buf, len, pieces, npieces);
  i2m_free(&buf);
  if (err != I2M_OK) ck_pvtu_pieces_free(pieces, *npieces);
  return err;
}

void ck_pvtu_pieces_free(char ***pieces, int npieces)
{
  for (int i = 0; *pieces && i < npieces; i++) i2m_free(&(*pieces)[i]);
  i2m_free(pieces);
}

/* ================================== dispatch =================================== */

static int ends_with(const char *s, const char *suf)
{
  size_t a = strlen(s), b = strlen(suf);
  return a >= b && strcasecmp(s + a - b, suf) == 0;
}

i2m_err_t ck_mesh_read(const char *path, ck_mesh_t *m) { return ck_mesh_read_progress(path, m, NULL); }

i2m_err_t ck_mesh_read_progress(const char *path, ck_mesh_t *m, ck_progress_t *pr)
{
  char *buf = NULL;
  size_t len = 0;
  memset(m, 0, sizeof *m);
  if (ends_with(path, ".pvtu")) return ck_pvtu_read(path, m);
  int fmt = ends_with(path, ".vtu") ? 1 : ends_with(path, ".mesh") ? 2 : ends_with(path, ".msh") ? 3 : 0;
  I2M_CHECK(fmt, I2M_ERR_ARG, "%s: unknown mesh format (expected .vtu, .pvtu, .mesh or .msh)",
            path);
  I2M_CALL(read_file(path, &buf, &len));
  m->path = path;
  rd_t r = {buf, buf + len, path, 0, pr, buf, 0};
  if (pr) pr->p.total = (int64_t)len;
  i2m_err_t err;
  if (fmt == 1) {
    strcpy(m->format, "vtu");
    err = read_vtu(buf, len, path, m, pr);
  } else if (fmt == 2) {
    strcpy(m->format, "medit");
    err = read_medit(&r, m);
  } else {
    strcpy(m->format, "gmsh");
    err = read_gmsh(&r, m);
  }
  i2m_free(&buf);
  if (err != I2M_OK) {
    ck_mesh_free(m);
    return err;
  }
  /* a file without triangles: keep empty arrays */
  if (!m->tri_label && m->ntri == 0) m->tri_labels_known = 0;
  return I2M_OK;
}
