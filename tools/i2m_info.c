/* i2m-info: prints what i2m reads from a label image (format, size, voxel type, geometry,
 * world bounding box, voxels per label), as text or as one JSON object.  A thin client of the
 * image layer: any reading error is printed as one line "i2m-info: <message>", exit status 1. */
#include "i2m/image.h"

#include <stdio.h>
#include <string.h>

static void usage(FILE *f)
{
  fprintf(f,
          "usage: i2m-info FILE [--json] [--allow-external-data]\n"
          "Reads a 3-D label image (NRRD .nrrd/.nhdr, NIfTI-1 .nii/.nii.gz/.hdr, MetaImage\n"
          ".mha/.mhd, Inrimage .inr/.inr.gz) and prints its format, dimensions, voxel type,\n"
          "spacing, origin and direction (world frame LPS, as ITK and 3D Slicer), world\n"
          "bounding box and the voxel count of every label value, with its tissue name when the\n"
          "image has names (a 3D Slicer segmentation .seg.nrrd, or a colour table <stem>.ctbl\n"
          "beside the image).\n"
          "  --json   print one JSON object instead of text\n"
          "  --allow-external-data  a detached header (.nhdr, .mhd) may name a data file outside\n"
          "           its own directory (refused by default)\n"
          "  --help   print this help\n"
          "Exit status: 0 success, 1 the image cannot be read, 2 bad command line.\n");
}

/* World bounding box of the voxels (outer faces, not centres): lo[3], hi[3]. */
static void world_bounds(const i2m_image_t *img, double lo[3], double hi[3])
{
  for (int r = 0; r < 3; r++) lo[r] = 1e300, hi[r] = -1e300;
  for (int corner = 0; corner < 8; corner++) {
    double g[3], w[3];
    for (int a = 0; a < 3; a++)
      g[a] = img->spacing[a] * ((corner >> a & 1) ? (double)img->n[a] - 0.5 : -0.5);
    i2m_image_grid_to_world(img, g, w);
    for (int r = 0; r < 3; r++) {
      if (w[r] < lo[r]) lo[r] = w[r];
      if (w[r] > hi[r]) hi[r] = w[r];
    }
  }
}

static void json_string(const char *s)
{
  putchar('"');
  for (; *s; s++) {
    unsigned char ch = (unsigned char)*s;
    if (ch == '"' || ch == '\\') printf("\\%c", ch);
    else if (ch < 0x20) printf("\\u%04x", ch);
    else putchar(ch);
  }
  putchar('"');
}

static void json_vec(const double v[3]) { printf("[%.17g, %.17g, %.17g]", v[0], v[1], v[2]); }

static void print_json(const i2m_image_t *img, i2m_image_format_t fmt)
{
  double lo[3], hi[3];
  world_bounds(img, lo, hi);
  printf("{\"file\": ");
  json_string(img->path);
  printf(", \"format\": \"%s\", \"dims\": [%lld, %lld, %lld], \"type\": \"%s\",\n",
         i2m_image_format_name(fmt), (long long)img->n[0], (long long)img->n[1],
         (long long)img->n[2], i2m_scalar_name(img->file_type));
  printf(" \"spacing\": ");
  json_vec(img->spacing);
  printf(", \"origin\": ");
  json_vec(img->origin);
  printf(",\n \"direction\": [");
  for (int r = 0; r < 3; r++) {
    json_vec(img->dir[r]);
    printf(r < 2 ? ", " : "],\n");
  }
  printf(" \"bounds\": [");
  json_vec(lo);
  printf(", ");
  json_vec(hi);
  printf("],\n \"labels_voxel_counts\": {");
  for (int l = 0; l < img->nlabels; l++)
    printf("%s\"%lld\": %lld", l ? ", " : "", (long long)img->label_value[l],
           (long long)img->label_count[l]);
  printf("}");
  if (img->names && img->names->n > 0) {
    printf(",\n \"label_names\": {");
    for (int64_t i = 0; i < img->names->n; i++) {
      printf("%s\"%lld\": ", i ? ", " : "", (long long)img->names->value[i]);
      json_string(img->names->name[i]);
    }
    printf("}");
  }
  printf("}\n");
}

static void print_text(const i2m_image_t *img, i2m_image_format_t fmt)
{
  double lo[3], hi[3];
  int64_t nvox = img->n[0] * img->n[1] * img->n[2];
  world_bounds(img, lo, hi);
  printf("file        %s\nformat      %s\ntype        %s\n", img->path, i2m_image_format_name(fmt),
         i2m_scalar_name(img->file_type));
  printf("dimensions  %lld x %lld x %lld (%lld voxels)\n", (long long)img->n[0],
         (long long)img->n[1], (long long)img->n[2], (long long)nvox);
  printf("spacing     %.10g %.10g %.10g mm\n", img->spacing[0], img->spacing[1], img->spacing[2]);
  printf("origin      %.10g %.10g %.10g (LPS world position of the centre of voxel 0,0,0)\n",
         img->origin[0], img->origin[1], img->origin[2]);
  for (int r = 0; r < 3; r++)
    printf("%s %10.7f %10.7f %10.7f%s\n", r ? "           " : "direction  ", img->dir[r][0],
           img->dir[r][1], img->dir[r][2],
           r == 2 ? (i2m_image_handedness(img) > 0 ? "   (det +1)" : "   (det -1: flips orientation)") : "");
  printf("bounds      x [%.6g, %.6g]  y [%.6g, %.6g]  z [%.6g, %.6g] mm (LPS, outer voxel faces)\n",
         lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]);
  printf("labels      %d values (background 0 included)\n", img->nlabels);
  printf("  %12s %14s %9s%s\n", "value", "voxels", "percent", img->names ? "  name" : "");
  for (int l = 0; l < img->nlabels; l++) {
    const char *name = i2m_label_name(img->names, img->label_value[l]);
    printf("  %12lld %14lld %8.4f%%%s%s\n", (long long)img->label_value[l], (long long)img->label_count[l],
           100.0 * (double)img->label_count[l] / (double)nvox, name ? "  " : "", name ? name : "");
  }
}

int main(int argc, char **argv)
{
  const char *file = NULL;
  int json = 0;
  i2m_image_read_opts_t ro = {.allow_external_data = false};
  for (int i = 1; i < argc; i++) {
    if (strcmp(argv[i], "--help") == 0 || strcmp(argv[i], "-h") == 0) {
      usage(stdout);
      return 0;
    } else if (strcmp(argv[i], "--json") == 0) {
      json = 1;
    } else if (strcmp(argv[i], "--allow-external-data") == 0) {
      ro.allow_external_data = true;
    } else if (argv[i][0] == '-' && argv[i][1] != '\0') {
      fprintf(stderr, "i2m-info: unknown option %s (try --help)\n", argv[i]);
      return 2;
    } else if (file) {
      fprintf(stderr, "i2m-info: one image file only (try --help)\n");
      return 2;
    } else {
      file = argv[i];
    }
  }
  if (!file) {
    fprintf(stderr, "i2m-info: no image file given (try --help)\n");
    return 2;
  }
  i2m_image_t *img = NULL;
  i2m_image_format_t fmt;
  if (i2m_image_read_with(file, &ro, &img, &fmt) != I2M_OK) {
    fprintf(stderr, "i2m-info: %s\n", i2m_error_message());
    return 1;
  }
  if (json) print_json(img, fmt);
  else print_text(img, fmt);
  i2m_image_destroy(&img);
  return 0;
}
