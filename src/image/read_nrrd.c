/* Image layer: the NRRD reader (teem's "nearly raw raster data", format versions 1 to 5).
 * Attached (.nrrd) and detached (.nhdr + "data file:") headers; raw and gzip encodings; every
 * spelling of the ten scalar types; little and big endian; "line skip" and "byte skip"
 * (-1: data at the end of a raw file).  Geometry from "space directions" + "space origin" in
 * any 3-D space (RAS and LAS converted to LPS), or from legacy "spacings".  A 4-D image whose
 * extra axis has a single sample is read as 3-D.
 *
 * 3D Slicer segmentations (.seg.nrrd: "SegmentN_Name:=...", "SegmentN_LabelValue:=...",
 * "SegmentN_Layer:=..." key/value pairs) are read as label images with the segment names as
 * tissue names.  One layer (3-D data): the voxels hold the label values, kept as they are.
 * Several layers (4-D data whose first axis, with direction "none", is the layer): each
 * (layer, LabelValue) segment becomes one label; the values are kept when no two segments
 * share one, else renumbered 1, 2, ... in the order of the segment index N (segments the
 * header does not declare after those, by layer and value).  A voxel in segments of several
 * layers takes the segment of its lowest layer (one warning gives the count). */
#include "image_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NRRD_FIELD 4096

/* A segment of a 3D Slicer segmentation, from its SegmentN_ keys. */
typedef struct {
  char *name;        /* owned, or NULL: SegmentN_Name (SegmentN_ID when there is no name) */
  int from_id;       /* name is the ID (a Name key replaces it) */
  int64_t value;     /* SegmentN_LabelValue (0: not given) */
  int64_t layer;     /* SegmentN_Layer (default 0) */
} nrrd_segment_t;

typedef struct {
  char type[128], encoding[64], endian[64], space[128], space_dim[64];
  char dimension[64], line_skip[64], byte_skip[64];
  char sizes[512], spacings[1024], directions[NRRD_FIELD], origin[1024], data_file[NRRD_FIELD];
  char data_path[NRRD_FIELD + 256];
  char data_name[8192]; /* "<header> (data file <data>)", for messages */
  char line[8192];
  int at_eof;        /* the header ran to the end of the file (no blank line) */
  int dim;           /* dimension */
  int64_t size[4];   /* sizes */
  int ax[3];         /* file axes kept as i, j, k */
  i2m_scalar_t type_id;
  int gzip, big_endian;
  int64_t lskip, bskip;
  nrrd_segment_t *seg; /* owned: [nseg] segments N = 0 .. nseg - 1 (a segmentation) */
  int nseg;
  int64_t layers;      /* a segmentation's layers (4-D: the size of axis 0), else 1 */
} nrrd_t;

/* ---- 3D Slicer segmentation keys ---- */

/* Segment N of the header, made room for. */
static i2m_err_t seg_at(nrrd_t *h, const char *path, long n, nrrd_segment_t **out)
{
  I2M_CHECK(n >= 0 && n < I2M_MAX_LABELS, I2M_ERR_INPUT, "%s: segment number %ld out of range", path, n);
  if (n >= h->nseg) {
    I2M_CALL(i2m_realloc((size_t)n + 1, sizeof *h->seg, &h->seg));
    memset(h->seg + h->nseg, 0, (size_t)(n + 1 - h->nseg) * sizeof *h->seg);
    h->nseg = (int)n + 1;
  }
  *out = &h->seg[n];
  return I2M_OK;
}

static i2m_err_t seg_set_name(nrrd_segment_t *g, const char *value, int from_id)
{
  if (g->name && (from_id || !g->from_id)) return I2M_OK; /* (a Name wins over an ID) */
  i2m_free(&g->name);
  size_t len = strlen(value) + 1;
  I2M_CALL(i2m_malloc(len, 1, &g->name));
  memcpy(g->name, value, len);
  g->from_id = from_id;
  return I2M_OK;
}

/* "SegmentN_Field:=value": the fields i2m uses (others, and every other key, are skipped). */
static i2m_err_t nrrd_keyvalue(nrrd_t *h, const char *path, const char *key, const char *value)
{
  char *end;
  if (strncmp(key, "Segment", 7) != 0 || key[7] < '0' || key[7] > '9') return I2M_OK;
  long n = strtol(key + 7, &end, 10);
  if (*end != '_') return I2M_OK;
  const char *field = end + 1;
  int is_name = !strcmp(field, "Name"), is_id = !strcmp(field, "ID");
  int is_value = !strcmp(field, "LabelValue"), is_layer = !strcmp(field, "Layer");
  if (!is_name && !is_id && !is_value && !is_layer) return I2M_OK;
  nrrd_segment_t *g = NULL;
  I2M_CALL(seg_at(h, path, n, &g));
  if (is_name || is_id) return seg_set_name(g, value, is_id);
  int64_t v;
  I2M_CHECK(image_parse_ints(value, &v, 1) && v >= 0, I2M_ERR_INPUT, "%s: bad %s \"%.40s\"", path, key, value);
  if (is_value) g->value = v;
  else g->layer = v;
  return I2M_OK;
}

static void nrrd_free(nrrd_t *h)
{
  for (int i = 0; i < h->nseg; i++) i2m_free(&h->seg[i].name);
  i2m_free(&h->seg);
}

static i2m_err_t nrrd_field(nrrd_t *h, const char *path, const char *key, const char *value)
{
  const struct {
    const char *name;
    char *dst;
    size_t cap;
  } fields[] = {
      {"type", h->type, sizeof h->type}, {"encoding", h->encoding, sizeof h->encoding},
      {"endian", h->endian, sizeof h->endian}, {"space", h->space, sizeof h->space},
      {"space dimension", h->space_dim, sizeof h->space_dim},
      {"dimension", h->dimension, sizeof h->dimension}, {"sizes", h->sizes, sizeof h->sizes},
      {"spacings", h->spacings, sizeof h->spacings},
      {"space directions", h->directions, sizeof h->directions},
      {"space origin", h->origin, sizeof h->origin},
      {"data file", h->data_file, sizeof h->data_file}, {"datafile", h->data_file, sizeof h->data_file},
      {"line skip", h->line_skip, sizeof h->line_skip}, {"lineskip", h->line_skip, sizeof h->line_skip},
      {"byte skip", h->byte_skip, sizeof h->byte_skip}, {"byteskip", h->byte_skip, sizeof h->byte_skip},
  };
  for (size_t i = 0; i < sizeof fields / sizeof fields[0]; i++) {
    if (!image_streq(key, fields[i].name)) continue;
    I2M_CHECK(strlen(value) < fields[i].cap, I2M_ERR_INPUT, "%s: header field \"%s\" is too long",
              path, key);
    strcpy(fields[i].dst, value);
    return I2M_OK;
  }
  return I2M_OK; /* fields i2m has no use for: content, kinds, centers, units, ... */
}

static i2m_err_t nrrd_read_header(image_stream_t *s, const char *path, nrrd_t *h)
{
  int64_t len;
  const unsigned char *p;
  size_t avail;
  I2M_CALL(image_stream_peek(s, 8, &p, &avail));
  I2M_CHECK(avail >= 8 && memcmp(p, "NRRD00", 6) == 0, I2M_ERR_INPUT,
            "%s: not a NRRD file (it does not start with \"NRRD000\")", path);
  I2M_CALL(image_stream_getline(s, h->line, sizeof h->line, &len));
  I2M_CHECK(len >= 8 && (strncmp(h->line, "NRRD000", 7) == 0 || strcmp(h->line, "NRRD00.01") == 0),
            I2M_ERR_INPUT, "%s: not a NRRD file (it does not start with \"NRRD000\")", path);
  for (int nlines = 0;; nlines++) {
    I2M_CHECK(nlines < 100000, I2M_ERR_INPUT, "%s: NRRD header without end", path);
    I2M_CALL(image_stream_getline(s, h->line, sizeof h->line, &len));
    if (len < 0) {
      h->at_eof = 1;
      return I2M_OK;
    }
    if (len == 0) return I2M_OK;
    if (h->line[0] == '#') continue;
    char *colon = strchr(h->line, ':');
    I2M_CHECK(colon, I2M_ERR_INPUT, "%s: bad NRRD header line \"%.60s\" (expected \"field: value\")",
              path, h->line);
    *colon = '\0';
    if (colon[1] == '=') { /* "key:=value" pairs: only a segmentation's are read */
      I2M_CALL(nrrd_keyvalue(h, path, h->line, colon + 2));
      continue;
    }
    I2M_CALL(nrrd_field(h, path, image_trim(h->line), image_trim(colon + 1)));
  }
}

/* Every NRRD spelling of a type: words compared after collapsing white space. */
static int nrrd_type(const char *text, i2m_scalar_t *t)
{
  static const struct {
    const char *name;
    i2m_scalar_t t;
  } types[] = {
      {"signed char", I2M_SCALAR_INT8}, {"int8", I2M_SCALAR_INT8}, {"int8_t", I2M_SCALAR_INT8},
      {"uchar", I2M_SCALAR_UINT8}, {"unsigned char", I2M_SCALAR_UINT8}, {"uint8", I2M_SCALAR_UINT8},
      {"uint8_t", I2M_SCALAR_UINT8}, {"short", I2M_SCALAR_INT16}, {"short int", I2M_SCALAR_INT16},
      {"signed short", I2M_SCALAR_INT16}, {"signed short int", I2M_SCALAR_INT16},
      {"int16", I2M_SCALAR_INT16}, {"int16_t", I2M_SCALAR_INT16}, {"ushort", I2M_SCALAR_UINT16},
      {"unsigned short", I2M_SCALAR_UINT16}, {"unsigned short int", I2M_SCALAR_UINT16},
      {"uint16", I2M_SCALAR_UINT16}, {"uint16_t", I2M_SCALAR_UINT16}, {"int", I2M_SCALAR_INT32},
      {"signed int", I2M_SCALAR_INT32}, {"int32", I2M_SCALAR_INT32}, {"int32_t", I2M_SCALAR_INT32},
      {"uint", I2M_SCALAR_UINT32}, {"unsigned int", I2M_SCALAR_UINT32},
      {"uint32", I2M_SCALAR_UINT32}, {"uint32_t", I2M_SCALAR_UINT32},
      {"longlong", I2M_SCALAR_INT64}, {"long long", I2M_SCALAR_INT64},
      {"long long int", I2M_SCALAR_INT64}, {"signed long long", I2M_SCALAR_INT64},
      {"signed long long int", I2M_SCALAR_INT64}, {"int64", I2M_SCALAR_INT64},
      {"int64_t", I2M_SCALAR_INT64}, {"ulonglong", I2M_SCALAR_UINT64},
      {"unsigned long long", I2M_SCALAR_UINT64}, {"unsigned long long int", I2M_SCALAR_UINT64},
      {"uint64", I2M_SCALAR_UINT64}, {"uint64_t", I2M_SCALAR_UINT64},
      {"float", I2M_SCALAR_FLOAT32}, {"double", I2M_SCALAR_FLOAT64},
  };
  char norm[128];
  size_t n = 0;
  for (const char *p = text; *p && n < sizeof norm - 1; p++) {
    int sp = *p == ' ' || *p == '\t';
    if (sp && (n == 0 || norm[n - 1] == ' ')) continue;
    norm[n++] = sp ? ' ' : *p;
  }
  norm[n] = '\0';
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
    if (image_streq(norm, types[i].name)) {
      *t = types[i].t;
      return 1;
    }
  return 0;
}

/* Parses "(a,b,c) none (d,e,f) ..." for @p naxes axes; none[a] = 1 for "none". */
static int nrrd_vectors(const char *text, int naxes, double vec[][3], int *none)
{
  const char *p = text;
  for (int a = 0; a < naxes; a++) {
    while (*p == ' ' || *p == '\t') p++;
    none[a] = strncmp(p, "none", 4) == 0;
    if (none[a]) {
      p += 4;
      continue;
    }
    if (*p++ != '(') return 0;
    for (int r = 0; r < 3; r++) {
      char *end;
      vec[a][r] = strtod(p, &end);
      if (end == p || !isfinite(vec[a][r])) return 0;
      for (p = end; *p == ' ' || *p == '\t'; p++) {}
      if (*p++ != (r < 2 ? ',' : ')')) return 0;
    }
  }
  while (*p == ' ' || *p == '\t') p++;
  return *p == '\0';
}

/* Which file axes are i, j, k: all three of a 3-D image, or the 3 of a 4-D one that are not
 * its single-sample axis (preferably one whose direction is "none"), or not a segmentation's
 * layer axis (the first, direction "none"). */
static i2m_err_t nrrd_axes(nrrd_t *h, const char *path, const int *none)
{
  int drop = -1;
  h->layers = 1;
  if (h->dim == 4) {
    for (int a = 0; a < 4; a++)
      if (h->size[a] == 1 && (drop < 0 || (none && none[a]))) drop = a;
    if (drop < 0 && h->nseg > 0 && (!none || none[0])) {
      drop = 0;
      h->layers = h->size[0];
    }
  }
  I2M_CHECK(h->dim == 3 || drop >= 0, I2M_ERR_UNSUPPORTED,
            "%s: not a 3-D image (dimension: %d, sizes: %s)", path, h->dim, h->sizes);
  for (int a = 0, k = 0; a < h->dim; a++)
    if (a != drop) h->ax[k++] = a;
  return I2M_OK;
}

/* Space name -> signs that turn its coordinates into LPS. */
static i2m_err_t nrrd_space(const nrrd_t *h, const char *path, double sign[3])
{
  static const struct {
    const char *name;
    double sx, sy;
  } spaces[] = {
      {"right-anterior-superior", -1, -1}, {"RAS", -1, -1}, {"left-anterior-superior", 1, -1},
      {"LAS", 1, -1}, {"left-posterior-superior", 1, 1}, {"LPS", 1, 1},
      {"scanner-xyz", 1, 1}, {"3D-right-handed", 1, 1}, {"3D-left-handed", 1, 1},
  };
  sign[0] = sign[1] = sign[2] = 1;
  if (!h->space[0]) {
    int64_t sd = 3;
    I2M_CHECK(!h->space_dim[0] || (image_parse_ints(h->space_dim, &sd, 1) && sd == 3),
              I2M_ERR_UNSUPPORTED, "%s: space dimension %s is not supported (only 3)", path, h->space_dim);
    return I2M_OK;
  }
  for (size_t i = 0; i < sizeof spaces / sizeof spaces[0]; i++)
    if (image_streq(h->space, spaces[i].name)) {
      sign[0] = spaces[i].sx;
      sign[1] = spaces[i].sy;
      return I2M_OK;
    }
  return I2M_ERROR(I2M_ERR_UNSUPPORTED, "%s: space \"%s\" is not supported (only 3-D spaces such "
                   "as left-posterior-superior)", path, h->space);
}

/* "spacings" of the kept axes (legacy geometry, no space): diagonal axes. */
static i2m_err_t nrrd_spacings(const nrrd_t *h, const char *path, double axis[3][3])
{
  double sp[4] = {1, 1, 1, 1};
  const char *p = h->spacings;
  for (int a = 0; h->spacings[0] && a < h->dim; a++) {
    char *end;
    sp[a] = strtod(p, &end);
    I2M_CHECK(end != p, I2M_ERR_INPUT, "%s: bad spacings \"%s\"", path, h->spacings);
    p = end;
  }
  for (int c = 0; c < 3; c++) {
    double v = sp[h->ax[c]];
    I2M_CALL(image_check_spacing(path, "spacings", h->ax[c], v));
    for (int r = 0; r < 3; r++) axis[c][r] = r == c ? v : 0;
  }
  return I2M_OK;
}

static i2m_err_t nrrd_geometry(nrrd_t *h, const char *path, double axis[3][3], double origin[3])
{
  double vec[4][3], sign[3];
  int none[4] = {0, 0, 0, 0};
  origin[0] = origin[1] = origin[2] = 0;
  if (!h->directions[0]) {
    I2M_CALL(nrrd_axes(h, path, NULL));
    return nrrd_spacings(h, path, axis);
  }
  I2M_CALL(nrrd_space(h, path, sign));
  I2M_CHECK(nrrd_vectors(h->directions, h->dim, vec, none), I2M_ERR_INPUT,
            "%s: bad space directions \"%.200s\" (expected %d vectors (x,y,z) or none)", path,
            h->directions, h->dim);
  I2M_CALL(nrrd_axes(h, path, none));
  for (int c = 0; c < 3; c++) {
    I2M_CHECK(!none[h->ax[c]], I2M_ERR_INPUT, "%s: space direction of axis %d is \"none\"", path, h->ax[c]);
    for (int r = 0; r < 3; r++) axis[c][r] = sign[r] * vec[h->ax[c]][r];
  }
  if (h->origin[0]) {
    double o[1][3];
    int onone[1];
    I2M_CHECK(nrrd_vectors(h->origin, 1, o, onone) && !onone[0], I2M_ERR_INPUT,
              "%s: bad space origin \"%.100s\" (expected (x,y,z))", path, h->origin);
    for (int r = 0; r < 3; r++) origin[r] = sign[r] * o[0][r];
  }
  return I2M_OK;
}

/* Checks and decodes the basic fields: dimension, sizes, type, encoding, endian, skips. */
static i2m_err_t nrrd_basic(nrrd_t *h, const char *path)
{
  int64_t d = 0;
  I2M_CHECK(h->dimension[0] && image_parse_ints(h->dimension, &d, 1) && d >= 1, I2M_ERR_INPUT,
            "%s: missing or bad \"dimension\" field", path);
  I2M_CHECK(d == 3 || d == 4, I2M_ERR_UNSUPPORTED, "%s: not a 3-D image (dimension: %lld)", path,
            (long long)d);
  h->dim = (int)d;
  I2M_CHECK(image_parse_ints(h->sizes, h->size, h->dim), I2M_ERR_INPUT,
            "%s: bad sizes \"%s\" (expected %d integers)", path, h->sizes, h->dim);
  for (int a = 0; a < h->dim; a++)
    I2M_CHECK(h->size[a] >= 1, I2M_ERR_INPUT, "%s: sizes \"%s\" must be positive", path, h->sizes);
  I2M_CHECK(h->type[0], I2M_ERR_INPUT, "%s: no \"type\" field", path);
  I2M_CHECK(strncmp(h->type, "block", 5) != 0, I2M_ERR_UNSUPPORTED, "%s: type \"block\" is not "
            "supported", path);
  I2M_CHECK(nrrd_type(h->type, &h->type_id), I2M_ERR_INPUT, "%s: unknown type \"%s\"", path, h->type);
  I2M_CHECK(h->encoding[0], I2M_ERR_INPUT, "%s: no \"encoding\" field", path);
  h->gzip = image_streq(h->encoding, "gzip") || image_streq(h->encoding, "gz");
  I2M_CHECK(h->gzip || image_streq(h->encoding, "raw"), I2M_ERR_UNSUPPORTED,
            "%s: encoding \"%s\" is not supported (only raw and gzip)", path, h->encoding);
  if (image_scalar_size(h->type_id) > 1) {
    I2M_CHECK(h->endian[0], I2M_ERR_INPUT, "%s: no \"endian\" field for %s data", path, h->type);
    h->big_endian = image_streq(h->endian, "big");
    I2M_CHECK(h->big_endian || image_streq(h->endian, "little"), I2M_ERR_INPUT,
              "%s: unknown endian \"%s\"", path, h->endian);
  }
  h->lskip = h->bskip = 0;
  I2M_CHECK(!h->line_skip[0] || (image_parse_ints(h->line_skip, &h->lskip, 1) && h->lskip >= 0),
            I2M_ERR_INPUT, "%s: bad line skip \"%s\"", path, h->line_skip);
  I2M_CHECK(!h->byte_skip[0] || (image_parse_ints(h->byte_skip, &h->bskip, 1) && h->bskip >= -1),
            I2M_ERR_INPUT, "%s: bad byte skip \"%s\"", path, h->byte_skip);
  I2M_CHECK(!(h->gzip && h->bskip < 0), I2M_ERR_INPUT, "%s: byte skip -1 needs raw encoding", path);
  return I2M_OK;
}

/* Skips @p n lines ("line skip") of the raw file. */
static i2m_err_t skip_lines(image_stream_t *s, int64_t n)
{
  for (int64_t i = 0; i < n; i++) {
    for (;;) {
      const unsigned char *p;
      size_t avail;
      I2M_CALL(image_stream_peek(s, 1, &p, &avail));
      I2M_CHECK(avail > 0, I2M_ERR_INPUT, "%s: line skip %lld goes past the end of the file",
                s->name, (long long)n);
      const unsigned char *nl = memchr(p, '\n', avail);
      image_stream_consume(s, nl ? (size_t)(nl - p) + 1 : avail);
      if (nl) break;
    }
  }
  return I2M_OK;
}

/* Opens the detached data file into @p ds, or checks that attached data follow the header. */
static i2m_err_t nrrd_open_data(nrrd_t *h, const char *path, int allow_external, image_stream_t *ds)
{
  if (!h->data_file[0]) {
    I2M_CHECK(!h->at_eof, I2M_ERR_INPUT, "%s: no data: the header names no data file and does not "
              "end with a blank line followed by the data", path);
    return I2M_OK;
  }
  I2M_CHECK(image_count_words(h->data_file) == 1 && strncmp(h->data_file, "LIST", 4) != 0,
            I2M_ERR_UNSUPPORTED, "%s: data split over several files (\"data file: %.100s\") is not "
            "supported", path, h->data_file);
  I2M_CALL(image_sibling_path(path, h->data_file, allow_external, h->data_path, sizeof h->data_path));
  i2m_err_t err = image_stream_open(h->data_path, ds);
  if (err != I2M_OK) {
    char msg[600];
    snprintf(msg, sizeof msg, "%s", i2m_error_message());
    return I2M_ERROR(err, "%s: cannot read its data file: %s", path, msg);
  }
  snprintf(h->data_name, sizeof h->data_name, "%s (data file %s)", path, h->data_file);
  ds->name = h->data_name;
  return I2M_OK;
}

/* Moves the data stream to the first voxel: line skip, then byte skip (gzip: decompressed). */
static i2m_err_t nrrd_position(nrrd_t *h, image_stream_t *s, const int64_t n[3])
{
  int64_t got;
  I2M_CALL(skip_lines(s, h->lskip));
  if (h->gzip) I2M_CALL(image_stream_begin_gzip(s));
  if (h->bskip == -1) { /* raw data at the end of the file */
    I2M_CALL(image_check_data_size(s, n, h->type_id));
    int64_t bytes = n[0] * n[1] * n[2] * (int64_t)image_scalar_size(h->type_id);
    return image_stream_seek(s, s->file_size - bytes);
  }
  I2M_CALL(image_stream_skip(s, h->bskip, &got));
  I2M_CHECK(got == h->bskip, I2M_ERR_INPUT, "%s: byte skip %lld goes past the end of the %s",
            s->name, (long long)h->bskip, h->gzip ? "gzip stream" : "file");
  return image_check_data_size(s, n, h->type_id);
}

/* ---- segmentations: names and layers ---- */

/* The first declared segment with label value @p value (in layer @p layer, or any when
 * layer < 0), or -1. */
static int seg_find(const nrrd_t *h, int64_t layer, int64_t value)
{
  for (int i = 0; i < h->nseg; i++)
    if (value != 0 && h->seg[i].value == value && (layer < 0 || h->seg[i].layer == layer)) return i;
  return -1;
}

/* Appends the name of segment @p s (if it has one) for label @p value. */
static i2m_err_t seg_add_name(const nrrd_t *h, int s, int64_t value, i2m_label_names_t *names)
{
  if (s < 0 || !h->seg[s].name || !h->seg[s].name[0]) return I2M_OK;
  return image_names_add(names, value, h->seg[s].name, strlen(h->seg[s].name));
}

/* One layer: the label values as they are, named by the segment of that value. */
static i2m_err_t seg_names_one_layer(const nrrd_t *h, i2m_image_t *img)
{
  I2M_CALL(image_names_create(img->nlabels, &img->names));
  for (int l = 1; l < img->nlabels; l++)
    I2M_CALL(seg_add_name(h, seg_find(h, -1, img->label_value[l]), img->label_value[l], img->names));
  return I2M_OK;
}

/* A (layer, label index) pair present in a layered segmentation: one output label. */
typedef struct {
  int64_t key;   /* order: the declared segment N, else nseg + pair */
  int64_t pair;  /* layer * nlabels + index in the file */
  int64_t layer; /* layer and label value in the file */
  int64_t file_value;
  int segment;   /* declared segment, or -1 */
  int64_t value; /* output label value */
  int64_t count; /* voxels that get it */
  int index;     /* output label index */
} seg_label_t;

static int cmp_key(const void *a, const void *b)
{
  int64_t x = ((const seg_label_t *)a)->key, y = ((const seg_label_t *)b)->key;
  return (x > y) - (x < y);
}

static int cmp_value(const void *a, const void *b)
{
  int64_t x = ((const seg_label_t *)a)->value, y = ((const seg_label_t *)b)->value;
  return (x > y) - (x < y);
}

/* The (layer, index) pairs the layered image @p rd holds: slot[layer * nlabels + index] = 1. */
static void seg_mark_present(const i2m_image_t *rd, int64_t layers, int32_t *slot)
{
  const int64_t nread = rd->n[0] * rd->n[1] * rd->n[2];
  for (int64_t v = 0; v < nread; v += layers)
    for (int64_t l = 0; l < layers; l++) {
      int idx = i2m_image_index(rd, v + l);
      if (idx != 0) slot[l * rd->nlabels + idx] = 1;
    }
}

/* The output labels (*labels, [*nl]) of the present pairs, in key order; slot[] then holds
 * each pair's position + 1 (0: background or absent). */
static i2m_err_t seg_labels(const nrrd_t *h, const i2m_image_t *rd, int32_t *slot, seg_label_t **labels, int *nl)
{
  const int64_t npairs = h->layers * rd->nlabels;
  int n = 0;
  for (int64_t p = 0; p < npairs; p++) n += slot[p] != 0;
  I2M_CHECK(n < I2M_MAX_LABELS, I2M_ERR_UNSUPPORTED, "%s: %d segments, more than %d", rd->path, n, I2M_MAX_LABELS - 1);
  I2M_CALL(i2m_calloc((size_t)n + 1, sizeof **labels, labels));
  seg_label_t *g = *labels;
  int k = 0;
  for (int64_t p = 0; p < npairs; p++) {
    if (!slot[p]) continue;
    g[k].pair = p;
    g[k].layer = p / rd->nlabels;
    g[k].file_value = rd->label_value[p % rd->nlabels];
    g[k].segment = seg_find(h, g[k].layer, g[k].file_value);
    g[k].key = g[k].segment >= 0 ? g[k].segment : h->nseg + p;
    k++;
  }
  for (int i = 0; i < n; i++) g[i].value = g[i].file_value;
  qsort(g, (size_t)n, sizeof *g, cmp_value);
  int shared = 0; /* do two segments share a label value? */
  for (int i = 1; i < n; i++) shared |= g[i].value == g[i - 1].value;
  qsort(g, (size_t)n, sizeof *g, cmp_key);
  for (int i = 0; i < n; i++) {
    if (shared) g[i].value = i + 1;
    slot[g[i].pair] = i + 1;
  }
  *nl = n;
  return I2M_OK;
}

/* Voxels of the layered image @p rd -> output slots (slot[] of seg_labels) in @p out, the
 * lowest layer's segment where several layers hold one; counts per slot; returns the number
 * of such overlapping voxels in *overlaps. */
static i2m_err_t seg_assign(const i2m_image_t *rd, int64_t layers, const int32_t *slot, seg_label_t *g,
                            i2m_image_t *out, int64_t *background, int64_t *overlaps)
{
  const int64_t nvox = out->n[0] * out->n[1] * out->n[2];
  *background = *overlaps = 0;
  for (int64_t v = 0; v < nvox; v++) {
    int32_t s = 0;
    int held = 0;
    for (int64_t l = 0; l < layers; l++) {
      int idx = i2m_image_index(rd, v * layers + l);
      if (idx == 0) continue;
      held++;
      if (!s) s = slot[l * rd->nlabels + idx];
    }
    *overlaps += held > 1;
    I2M_CALL(image_store_index(out, v, (unsigned)s));
    if (s) g[s - 1].count++;
    else (*background)++;
  }
  return I2M_OK;
}

/* The label table of @p out from the slots it holds: index 0 the background, then the
 * segments with voxels by increasing value; voxels renumbered, names attached. */
static i2m_err_t seg_label_table(const nrrd_t *h, seg_label_t *g, int n, int64_t background, i2m_image_t *out)
{
  uint16_t *remap = NULL; /* [n + 1] slot -> output index */
  I2M_CALL(i2m_calloc((size_t)n + 1, sizeof *remap, &remap));
  for (int i = 0; i < n; i++) g[i].index = i + 1; /* (the slot, kept through the sort) */
  qsort(g, (size_t)n, sizeof *g, cmp_value);
  int nl = 1;
  for (int i = 0; i < n; i++) nl += g[i].count > 0;
  i2m_err_t err = i2m_calloc((size_t)nl, sizeof(int64_t), &out->label_value);
  if (err == I2M_OK) err = i2m_calloc((size_t)nl, sizeof(int64_t), &out->label_count);
  if (err == I2M_OK) err = image_names_create(nl, &out->names);
  if (err == I2M_OK) {
    out->nlabels = nl;
    out->label_count[0] = background;
    for (int i = 0, k = 1; i < n && err == I2M_OK; i++) {
      if (!g[i].count) continue;
      remap[g[i].index] = (uint16_t)k;
      out->label_value[k] = g[i].value;
      out->label_count[k++] = g[i].count;
      err = seg_add_name(h, g[i].segment, g[i].value, out->names);
    }
  }
  const int64_t nvox = out->n[0] * out->n[1] * out->n[2];
  for (int64_t v = 0; err == I2M_OK && v < nvox; v++) err = image_store_index(out, v, remap[i2m_image_index(out, v)]);
  i2m_free(&remap);
  return err;
}

/* A layered segmentation read as one image of layers x n0 x n1 x n2 voxels (@p rd) -> the
 * label image of n0 x n1 x n2 voxels (*out). */
static i2m_err_t seg_merge_layers(const nrrd_t *h, const i2m_image_t *rd, const int64_t n[3], i2m_image_t **out)
{
  int32_t *slot = NULL; /* [layers][nlabels of rd] */
  seg_label_t *g = NULL;
  int ng = 0;
  int64_t background = 0, overlaps = 0;
  I2M_CALL(i2m_calloc((size_t)(h->layers * rd->nlabels), sizeof *slot, &slot));
  seg_mark_present(rd, h->layers, slot);
  i2m_err_t err = seg_labels(h, rd, slot, &g, &ng);
  if (err == I2M_OK) err = image_alloc(rd->path, n, out);
  if (err == I2M_OK) {
    memcpy((*out)->spacing, rd->spacing, sizeof rd->spacing);
    memcpy((*out)->origin, rd->origin, sizeof rd->origin);
    memcpy((*out)->dir, rd->dir, sizeof rd->dir);
    (*out)->file_type = rd->file_type;
    err = seg_assign(rd, h->layers, slot, g, *out, &background, &overlaps);
  }
  if (err == I2M_OK) err = seg_label_table(h, g, ng, background, *out);
  if (err == I2M_OK && overlaps)
    i2m_warn("warning: %s: %lld voxels lie in segments of several layers; each was given the segment of its "
             "lowest layer", rd->path, (long long)overlaps);
  i2m_free(&slot);
  i2m_free(&g);
  return err;
}

/* After the voxels: a segmentation's names, and its layers merged into one label image. */
static i2m_err_t seg_finish(const nrrd_t *h, const image_stream_t *s, const int64_t n[3], i2m_image_t **img)
{
  if (s->header_only) {
    (*img)->n[0] = n[0]; /* (no voxels: only the size changes) */
    return I2M_OK;
  }
  if (h->layers == 1) {
    I2M_CALL(seg_names_one_layer(h, *img));
    image_names_keep_present((*img)->names, *img);
    return I2M_OK;
  }
  i2m_image_t *merged = NULL;
  i2m_err_t err = seg_merge_layers(h, *img, n, &merged);
  if (err != I2M_OK) {
    i2m_image_destroy(&merged);
    return err;
  }
  i2m_image_destroy(img);
  *img = merged;
  return I2M_OK;
}
static i2m_err_t nrrd_read(nrrd_t *h, image_stream_t *s, const char *path, image_stream_t *ds,
                           i2m_image_t **out)
{
  double axis[3][3], origin[3];
  int64_t n[3];
  I2M_CALL(nrrd_read_header(s, path, h));
  I2M_CALL(nrrd_basic(h, path));
  I2M_CALL(nrrd_geometry(h, path, axis, origin));
  for (int c = 0; c < 3; c++) n[c] = h->size[h->ax[c]];
  I2M_CHECK(h->layers <= ((int64_t)1 << 40) / n[0], I2M_ERR_INPUT, "%s: sizes \"%s\" are too large", path, h->sizes);
  const int64_t nread[3] = {h->layers * n[0], n[1], n[2]}; /* (a segmentation's layers: i fastest) */
  I2M_CALL(nrrd_open_data(h, path, s->allow_external, ds));
  image_stream_t *data = h->data_file[0] ? ds : s;
  I2M_CALL(nrrd_position(h, data, nread));
  I2M_CALL(image_alloc(path, nread, out));
  (*out)->n[0] = n[0]; /* (the geometry's range check is on the spatial size) */
  I2M_CALL(image_set_geometry(*out, axis, origin));
  (*out)->n[0] = nread[0];
  image_voxels_t vf = {h->type_id, h->big_endian, 0, 1.0, 0.0};
  I2M_CALL(image_read_body(s, data, &vf, *out));
  return h->nseg > 0 ? seg_finish(h, s, n, out) : I2M_OK;
}

i2m_err_t image_read_nrrd(image_stream_t *s, const char *path, i2m_image_t **out)
{
  nrrd_t *h = NULL;
  image_stream_t ds;
  memset(&ds, 0, sizeof ds);
  *out = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *h, &h));
  i2m_err_t err = nrrd_read(h, s, path, &ds, out);
  image_stream_close(&ds);
  nrrd_free(h);
  i2m_free(&h);
  if (err != I2M_OK) i2m_image_destroy(out);
  return err;
}
