/* Image layer: tissue names of label values (i2m_label_names_t).  The readers of the files
 * that carry names fill it: a 3D Slicer colour table <stem>.ctbl beside the image (read
 * here: lines "value name r g b a", '#' comments), or a 3D Slicer segmentation's segment
 * names (read_nrrd.c).  Only the names of labels the image holds are kept. */
#include "image_impl.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

/* The entry of label value, or -1. */
static int64_t name_index(const i2m_label_names_t *names, int64_t value)
{
  for (int64_t i = 0; names && i < names->n; i++)
    if (names->value[i] == value) return i;
  return -1;
}

const char *i2m_label_name(const i2m_label_names_t *names, int64_t value)
{
  const int64_t i = name_index(names, value);
  return i < 0 ? NULL : names->name[i];
}

int32_t i2m_label_colour(const i2m_label_names_t *names, int64_t value)
{
  const int64_t i = name_index(names, value);
  return i < 0 || !names->colour ? -1 : names->colour[i];
}

void i2m_label_names_destroy(i2m_label_names_t **names)
{
  if (!names || !*names) return;
  for (int64_t i = 0; i < (*names)->n; i++) i2m_free(&(*names)->name[i]);
  i2m_free(&(*names)->name);
  i2m_free(&(*names)->value);
  i2m_free(&(*names)->colour);
  i2m_free(names);
}

i2m_err_t image_names_create(int64_t cap, i2m_label_names_t **out)
{
  *out = NULL;
  i2m_label_names_t *nm = NULL;
  I2M_CALL(i2m_calloc(1, sizeof *nm, &nm));
  i2m_err_t err = i2m_calloc((size_t)(cap > 0 ? cap : 1), sizeof *nm->value, &nm->value);
  if (err == I2M_OK) err = i2m_calloc((size_t)(cap > 0 ? cap : 1), sizeof *nm->name, &nm->name);
  if (err == I2M_OK) err = i2m_calloc((size_t)(cap > 0 ? cap : 1), sizeof *nm->colour, &nm->colour);
  if (err != I2M_OK) {
    i2m_label_names_destroy(&nm);
    return err;
  }
  *out = nm;
  return I2M_OK;
}

i2m_err_t image_names_add(i2m_label_names_t *names, int64_t value, const char *name, size_t len)
{
  char *copy = NULL;
  I2M_CALL(i2m_malloc(len + 1, 1, &copy));
  memcpy(copy, name, len);
  copy[len] = '\0';
  names->value[names->n] = value;
  names->colour[names->n] = -1;
  names->name[names->n++] = copy;
  return I2M_OK;
}

/* ---- .ctbl colour tables ---- */

/* One table line "value name r g b a" (the name may hold spaces: every word between the value
 * and the four colour components); *rgb = 0xRRGGBB.  Returns 0 on a malformed line. */
static int ctbl_line(char *line, int64_t *value, char **name, size_t *len, int32_t *rgb)
{
  char *p = image_trim(line);
  if (image_count_words(p) < 6) return 0;
  char *end = p + strlen(p);
  int64_t c[4];
  for (int w = 3; w >= 0; w--) { /* the colour words a, b, g, r, from the end */
    while (end > p && end[-1] != ' ' && end[-1] != '\t') end--;
    if (!image_parse_ints(end, &c[w], 1) || c[w] < 0 || c[w] > 255) return 0;
    while (end > p && (end[-1] == ' ' || end[-1] == '\t')) end--;
    *end = '\0';
  }
  *rgb = (int32_t)(c[0] << 16 | c[1] << 8 | c[2]);
  char *sep = p + strcspn(p, " \t");
  *sep = '\0';
  if (!image_parse_ints(p, value, 1)) return 0;
  *name = image_trim(sep + 1);
  *len = strlen(*name);
  return *len > 0;
}

static int names_have(const i2m_label_names_t *names, int64_t value)
{
  return i2m_label_name(names, value) != NULL;
}

static i2m_err_t ctbl_parse(FILE *f, const char *path, i2m_label_names_t *names, int64_t cap)
{
  char line[4096];
  for (int64_t lineno = 1; fgets(line, sizeof line, f); lineno++) {
    size_t n = strlen(line);
    I2M_CHECK(n + 1 < sizeof line || line[n - 1] == '\n', I2M_ERR_INPUT, "%s:%lld: line too long", path,
              (long long)lineno);
    char *p = image_trim(line);
    if (*p == '\0' || *p == '#') continue;
    int64_t value;
    char *name;
    size_t len;
    int32_t rgb;
    I2M_CHECK(ctbl_line(p, &value, &name, &len, &rgb), I2M_ERR_INPUT,
              "%s:%lld: expected \"value name r g b a\" (colours 0-255)", path, (long long)lineno);
    I2M_CHECK(!names_have(names, value), I2M_ERR_INPUT, "%s:%lld: value %lld named twice", path,
              (long long)lineno, (long long)value);
    I2M_CHECK(names->n < cap, I2M_ERR_INPUT, "%s: more lines than at first", path);
    I2M_CALL(image_names_add(names, value, name, len));
    names->colour[names->n - 1] = rgb;
  }
  I2M_CHECK(!ferror(f), I2M_ERR_IO, "%s: read error", path);
  return I2M_OK;
}

/* Lines of a file (an upper bound on the names it holds). */
static int64_t count_lines(FILE *f)
{
  int64_t n = 1;
  for (int ch; (ch = getc(f)) != EOF;) n += ch == '\n';
  rewind(f);
  return n;
}

i2m_err_t image_names_read_ctbl(const char *path, i2m_label_names_t **out)
{
  *out = NULL;
  FILE *f = fopen(path, "r");
  I2M_CHECK(f, I2M_ERR_IO, "%s: cannot open the colour table", path);
  const int64_t cap = count_lines(f);
  i2m_err_t err = image_names_create(cap, out);
  if (err == I2M_OK) err = ctbl_parse(f, path, *out, cap);
  fclose(f);
  if (err != I2M_OK) i2m_label_names_destroy(out);
  return err;
}

/* ---- attaching names to an image ---- */

static int image_has_value(const i2m_image_t *img, int64_t value)
{
  for (int l = 0; l < img->nlabels; l++)
    if (img->label_value[l] == value) return 1;
  return 0;
}

void image_names_keep_present(i2m_label_names_t *names, const i2m_image_t *img)
{
  int64_t k = 0;
  for (int64_t i = 0; i < names->n; i++) {
    if (!image_has_value(img, names->value[i])) {
      i2m_free(&names->name[i]);
      continue;
    }
    names->value[k] = names->value[i];
    names->colour[k] = names->colour[i];
    names->name[k++] = names->name[i];
  }
  names->n = k;
}

/* The image file's name without its image extension, with ".ctbl", into out[cap]; 0 when
 * the name has none of the extensions. */
static int ctbl_path_for(const char *path, char *out, size_t cap)
{
  static const char *const exts[] = {".nii.gz", ".inr.gz", ".nrrd", ".nhdr", ".nii", ".hdr",
                                     ".img", ".mha", ".mhd", ".inr"};
  const size_t n = strlen(path);
  for (size_t e = 0; e < sizeof exts / sizeof *exts; e++) {
    const size_t k = strlen(exts[e]);
    if (n < k || !image_streq(path + n - k, exts[e])) continue;
    if (n - k + sizeof ".ctbl" > cap) return 0;
    memcpy(out, path, n - k);
    strcpy(out + n - k, ".ctbl");
    return 1;
  }
  return 0;
}

void image_attach_ctbl(i2m_image_t *img, const char *path)
{
  char ctbl[4096];
  struct stat st;
  if (img->names || !ctbl_path_for(path, ctbl, sizeof ctbl) || stat(ctbl, &st) != 0) return;
  if (image_names_read_ctbl(ctbl, &img->names) != I2M_OK) { /* (names are a nicety: never fail the read) */
    i2m_warn("warning: %s; the colour table is ignored", i2m_error_message());
    i2m_error_clear();
    return;
  }
  image_names_keep_present(img->names, img);
}
