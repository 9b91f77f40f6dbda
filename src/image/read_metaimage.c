/* Image layer: the MetaImage reader (ITK's MetaIO: .mha with ElementDataFile = LOCAL, .mhd
 * with a separate data file).  Binary data only, raw or zlib-compressed (CompressedData),
 * either byte order; one channel.  World is LPS, as in ITK.  TransformMatrix (alias Rotation,
 * Orientation) is read as ITK's MetaImageIO does: its values, in file order, are the world
 * direction of index axis 0, then of axis 1, then of axis 2, i.e. dir[r][c] = M[c*NDims + r]. */
#include "image_impl.h"

#include <string.h>

#define META_VALUE 1024

typedef struct {
  char ndims[64], dim_size[256], type[64], spacing[512], size[512], offset[512], matrix[1024];
  char binary[64], msb[64], compressed[64], header_size[64], channels[64], object[64];
  char data_file[META_VALUE];
  char data_path[META_VALUE + 256];
  char data_name[8192]; /* "<header> (data file <data>)", for messages */
  char line[8192];
  int nd;
  int64_t n[4];
} meta_t;

static i2m_err_t meta_field(meta_t *m, const char *path, const char *key, const char *value, int *last)
{
  const struct {
    const char *name;
    char *dst;
    size_t cap;
  } fields[] = {
      {"NDims", m->ndims, sizeof m->ndims}, {"DimSize", m->dim_size, sizeof m->dim_size},
      {"ElementType", m->type, sizeof m->type}, {"ElementSpacing", m->spacing, sizeof m->spacing},
      {"ElementSize", m->size, sizeof m->size}, {"Offset", m->offset, sizeof m->offset},
      {"Position", m->offset, sizeof m->offset}, {"Origin", m->offset, sizeof m->offset},
      {"TransformMatrix", m->matrix, sizeof m->matrix}, {"Rotation", m->matrix, sizeof m->matrix},
      {"Orientation", m->matrix, sizeof m->matrix}, {"BinaryData", m->binary, sizeof m->binary},
      {"BinaryDataByteOrderMSB", m->msb, sizeof m->msb}, {"ElementByteOrderMSB", m->msb, sizeof m->msb},
      {"CompressedData", m->compressed, sizeof m->compressed},
      {"HeaderSize", m->header_size, sizeof m->header_size},
      {"ElementNumberOfChannels", m->channels, sizeof m->channels},
      {"ObjectType", m->object, sizeof m->object},
      {"ElementDataFile", m->data_file, sizeof m->data_file},
  };
  *last = image_streq(key, "ElementDataFile");
  for (size_t i = 0; i < sizeof fields / sizeof fields[0]; i++) {
    if (!image_streq(key, fields[i].name)) continue;
    I2M_CHECK(strlen(value) < fields[i].cap, I2M_ERR_INPUT, "%s: header field %s is too long", path, key);
    strcpy(fields[i].dst, value);
    return I2M_OK;
  }
  return I2M_OK; /* CompressedDataSize, CenterOfRotation, AnatomicalOrientation, ... */
}

/* Reads "Key = Value" lines up to ElementDataFile, which ends the header. */
static i2m_err_t meta_read_header(image_stream_t *s, const char *path, meta_t *m)
{
  for (int nlines = 0; nlines < 10000; nlines++) {
    int64_t len;
    int last;
    I2M_CALL(image_stream_getline(s, m->line, sizeof m->line, &len));
    I2M_CHECK(len >= 0, I2M_ERR_INPUT, "%s: the MetaImage header has no ElementDataFile line", path);
    char *line = image_trim(m->line);
    if (!line[0]) continue;
    char *eq = strchr(line, '=');
    I2M_CHECK(eq, I2M_ERR_INPUT, "%s: bad MetaImage header line \"%.60s\" (expected \"Key = "
              "Value\")", path, line);
    *eq = '\0';
    I2M_CALL(meta_field(m, path, image_trim(line), image_trim(eq + 1), &last));
    if (last) return I2M_OK;
  }
  return I2M_ERROR(I2M_ERR_INPUT, "%s: MetaImage header without end", path);
}

static int meta_true(const char *v) { return image_streq(v, "True") || image_streq(v, "1"); }

static i2m_err_t meta_type(const char *path, const char *name, i2m_scalar_t *t)
{
  static const struct {
    const char *name;
    i2m_scalar_t t;
  } types[] = {
      {"MET_CHAR", I2M_SCALAR_INT8},       {"MET_UCHAR", I2M_SCALAR_UINT8},
      {"MET_SHORT", I2M_SCALAR_INT16},     {"MET_USHORT", I2M_SCALAR_UINT16},
      {"MET_INT", I2M_SCALAR_INT32},       {"MET_UINT", I2M_SCALAR_UINT32},
      {"MET_LONG", I2M_SCALAR_INT32},      {"MET_ULONG", I2M_SCALAR_UINT32}, /* 4 bytes in MetaIO */
      {"MET_LONG_LONG", I2M_SCALAR_INT64}, {"MET_ULONG_LONG", I2M_SCALAR_UINT64},
      {"MET_FLOAT", I2M_SCALAR_FLOAT32},   {"MET_DOUBLE", I2M_SCALAR_FLOAT64},
  };
  for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
    if (image_streq(name, types[i].name)) {
      *t = types[i].t;
      return I2M_OK;
    }
  return I2M_ERROR(name[0] ? I2M_ERR_UNSUPPORTED : I2M_ERR_INPUT,
                   "%s: %s element type \"%s\" (a label image needs a scalar integer or real type)",
                   path, name[0] ? "unsupported" : "missing", name);
}

/* NDims and DimSize: 3, or 4 with a last size of 1. */
static i2m_err_t meta_dims(meta_t *m, const char *path)
{
  int64_t nd = 0;
  I2M_CHECK(image_parse_ints(m->ndims, &nd, 1), I2M_ERR_INPUT, "%s: missing or bad NDims", path);
  I2M_CHECK(nd == 3 || nd == 4, I2M_ERR_UNSUPPORTED, "%s: not a 3-D image (NDims = %lld)", path,
            (long long)nd);
  m->nd = (int)nd;
  I2M_CHECK(image_parse_ints(m->dim_size, m->n, m->nd), I2M_ERR_INPUT,
            "%s: bad DimSize \"%s\" (expected %d integers)", path, m->dim_size, m->nd);
  for (int a = 0; a < m->nd; a++)
    I2M_CHECK(m->n[a] >= 1, I2M_ERR_INPUT, "%s: DimSize \"%s\" must be positive", path, m->dim_size);
  I2M_CHECK(m->nd == 3 || m->n[3] == 1, I2M_ERR_UNSUPPORTED,
            "%s: not a 3-D image (NDims = 4, DimSize = %s)", path, m->dim_size);
  return I2M_OK;
}

static i2m_err_t meta_geometry(const meta_t *m, const char *path, double axis[3][3], double origin[3])
{
  double sp[4] = {1, 1, 1, 1}, o[4] = {0, 0, 0, 0}, M[16];
  const char *spacing = m->spacing[0] ? m->spacing : m->size;
  int nd = m->nd;
  I2M_CHECK(!spacing[0] || image_parse_doubles(spacing, sp, nd), I2M_ERR_INPUT,
            "%s: bad ElementSpacing \"%s\" (expected %d numbers)", path, spacing, nd);
  I2M_CHECK(!m->offset[0] || image_parse_doubles(m->offset, o, nd), I2M_ERR_INPUT,
            "%s: bad Offset \"%s\" (expected %d numbers)", path, m->offset, nd);
  for (int i = 0; i < nd * nd; i++) M[i] = i % (nd + 1) == 0; /* identity */
  I2M_CHECK(!m->matrix[0] || image_parse_doubles(m->matrix, M, nd * nd), I2M_ERR_INPUT,
            "%s: bad TransformMatrix \"%s\" (expected %d numbers)", path, m->matrix, nd * nd);
  for (int c = 0; c < 3; c++) {
    I2M_CALL(image_check_spacing(path, "ElementSpacing", c, sp[c]));
    origin[c] = o[c];
    for (int r = 0; r < 3; r++) axis[c][r] = M[c * nd + r] * sp[c];
  }
  return I2M_OK;
}

/* Binary, channels, byte order and compression. */
static i2m_err_t meta_storage(const meta_t *m, const char *path, image_voxels_t *vf, int *zlib)
{
  int64_t ch = 1;
  I2M_CHECK(!m->object[0] || image_streq(m->object, "Image"), I2M_ERR_UNSUPPORTED,
            "%s: ObjectType is \"%s\", not Image", path, m->object);
  I2M_CHECK(!m->binary[0] || meta_true(m->binary), I2M_ERR_UNSUPPORTED,
            "%s: text (BinaryData = False) MetaImage data is not supported", path);
  I2M_CHECK(!m->channels[0] || (image_parse_ints(m->channels, &ch, 1) && ch == 1),
            I2M_ERR_UNSUPPORTED, "%s: ElementNumberOfChannels = %s (only 1 is supported)", path,
            m->channels);
  I2M_CALL(meta_type(path, m->type, &vf->type));
  vf->big_endian = meta_true(m->msb);
  *zlib = meta_true(m->compressed);
  return I2M_OK;
}

/* Opens the data: after the header (LOCAL) or in the named file, past HeaderSize bytes. */
static i2m_err_t meta_position(meta_t *m, image_stream_t *s, const char *path, image_stream_t *ds,
                               int zlib, i2m_scalar_t t, image_stream_t **data)
{
  int64_t skip = 0, got, n[3] = {m->n[0], m->n[1], m->n[2]};
  *data = s;
  I2M_CHECK(!m->header_size[0] || (image_parse_ints(m->header_size, &skip, 1) && skip >= -1),
            I2M_ERR_INPUT, "%s: bad HeaderSize \"%s\"", path, m->header_size);
  if (!image_streq(m->data_file, "LOCAL")) {
    I2M_CHECK(image_count_words(m->data_file) == 1 && !strchr(m->data_file, '%') &&
              !image_streq(m->data_file, "LIST"), I2M_ERR_UNSUPPORTED,
              "%s: data split over several files (ElementDataFile = %.100s) is not supported",
              path, m->data_file);
    I2M_CALL(image_sibling_path(path, m->data_file, s->allow_external, m->data_path, sizeof m->data_path));
    i2m_err_t err = image_stream_open(m->data_path, ds);
    if (err != I2M_OK) {
      char msg[600];
      snprintf(msg, sizeof msg, "%s", i2m_error_message());
      return I2M_ERROR(err, "%s: cannot read its data file: %s", path, msg);
    }
    snprintf(m->data_name, sizeof m->data_name, "%s (data file %s)", path, m->data_file);
    ds->name = m->data_name;
    *data = ds;
    if (skip == -1 && !zlib) { /* raw data at the end of the file */
      I2M_CALL(image_check_data_size(ds, n, t));
      return image_stream_seek(ds, ds->file_size - n[0] * n[1] * n[2] * (int64_t)image_scalar_size(t));
    }
    I2M_CALL(image_stream_skip(ds, skip > 0 ? skip : 0, &got));
    I2M_CHECK(got == (skip > 0 ? skip : 0), I2M_ERR_INPUT, "%s: HeaderSize %lld goes past the end "
              "of the file", ds->name, (long long)skip);
  }
  if (zlib) I2M_CALL(image_stream_begin_gzip(*data));
  return image_check_data_size(*data, n, t);
}

static i2m_err_t meta_read(meta_t *m, image_stream_t *s, const char *path, image_stream_t *ds,
                           i2m_image_t **out)
{
  double axis[3][3], origin[3];
  image_voxels_t vf = {I2M_SCALAR_UINT8, 0, 0, 1.0, 0.0};
  image_stream_t *data;
  int zlib = 0;
  I2M_CALL(meta_read_header(s, path, m));
  I2M_CALL(meta_dims(m, path));
  I2M_CALL(meta_storage(m, path, &vf, &zlib));
  I2M_CALL(meta_geometry(m, path, axis, origin));
  I2M_CALL(meta_position(m, s, path, ds, zlib, vf.type, &data));
  I2M_CALL(image_alloc(path, m->n, out));
  I2M_CALL(image_set_geometry(*out, axis, origin));
  return image_read_body(s, data, &vf, *out);
}

i2m_err_t image_read_metaimage(image_stream_t *s, const char *path, i2m_image_t **out)
{
  meta_t *m = NULL;
  image_stream_t ds;
  memset(&ds, 0, sizeof ds);
  *out = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *m, &m));
  i2m_err_t err = meta_read(m, s, path, &ds, out);
  image_stream_close(&ds);
  i2m_free(&m);
  if (err != I2M_OK) i2m_image_destroy(out);
  return err;
}
