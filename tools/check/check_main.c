/* i2m-check: command line, thresholds and exit code.
 *   i2m-check MESH [--image IMAGE] [--json] [--plot DIR] [thresholds]
 * Exit 0: valid mesh and every threshold met; 1: invalid mesh or a threshold violated;
 * 2: the mesh or the image cannot be read, or bad usage (one line "i2m-check: <message>"). */
#include "check.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static const char *USAGE =
    "usage: i2m-check MESH [--image IMAGE] [--json] [--plot DIR [--slice AXIS=V]...] [--quiet]\n"
    "                 [thresholds]\n"
    "  MESH                 .vtu, .mesh (Medit) or .msh (Gmsh 4.1 or 2.2) file, or a .pvtu: its\n"
    "                       pieces stitched by GlobalNodeId, the seams checked\n"
    "  --image IMAGE        label image for fidelity figures (NRRD, NIfTI, MetaImage, INR)\n"
    "  --allow-external-data  the image's detached header may name a data file outside its\n"
    "                       directory (refused by default)\n"
    "  --json               print one JSON object instead of the summary\n"
    "  --no-distances       with --image: volumes, labels and components only (no interface\n"
    "                       distances: seconds instead of a minute on large meshes)\n"
    "  --plot DIR           write DIR/dihedral_histogram.svg and cross-sections of the mesh:\n"
    "                       DIR/cross_section_x.svg, _y.svg, _z.svg (the mid-planes of the\n"
    "                       image's world box, or of the mesh's box without --image), each\n"
    "                       label in its own colour (the .ctbl beside the image where they\n"
    "                       are distinct), axes in world mm, a scale bar, a legend\n"
    "  --slice AXIS=F       with --plot: cut at a fraction F in 0..1 of that range instead\n"
    "  --slice AXIS=Cmm     ... or at the world coordinate C in mm (AXIS x, y or z; repeat\n"
    "                       for more pictures: cross_section_z.svg, cross_section_z_2.svg)\n"
    "  --quiet              no progress lines on stderr (errors only)\n"
    "  --progress-interval S  at most one progress line per phase every S seconds (2)\n"
    "thresholds (exit 1 when violated):\n"
    "  --max-ratio R                 radius-edge ratio of every tetrahedron <= R\n"
    "  --min-facet-angle DEG         planar angles of interface triangles >= DEG\n"
    "  --min-dihedral DEG            smallest dihedral angle of every tetrahedron >= DEG\n"
    "  --max-dihedral DEG            largest dihedral angle of every tetrahedron <= DEG\n"
    "  --facet-angle-exceptions F    ... except a fraction F of the triangles (default 0)\n"
    "  --max-hausdorff MM            two-sided mesh/image interface distance <= MM (--image)\n"
    "  --max-mesh-to-image MM        distance from every mesh interface point to the image's <= MM\n"
    "  --max-p99 MM                  99th percentile of the two-sided distance <= MM (--image)\n"
    "  --max-volume-error PCT        |volume error| <= PCT for labels of >= N voxels (--image)\n"
    "  --volume-min-voxels N         N for --max-volume-error (default 10000)\n"
    "  --require-labels N            every label of >= N voxels is in the mesh (--image)\n"
    "  --require-whole N             every 6-connected image component of >= N voxels of a label\n"
    "                                is one face-connected piece of tets of that label (--image)\n"
    "exit status: 0 valid and thresholds met, 1 invalid or violated, 2 unreadable / usage\n";

static int fail_usage(const char *fmt, const char *a)
{
  fprintf(stderr, "i2m-check: ");
  fprintf(stderr, fmt, a);
  fprintf(stderr, " (see i2m-check --help)\n");
  return 2;
}

static int parse_num(const char *s, double *v)
{
  char *e;
  *v = strtod(s, &e);
  return e != s && *e == '\0' && isfinite(*v);
}

typedef struct {
  const char *mesh, *image, *plot;
  int json, no_distances, allow_external_data, quiet;
  double progress_interval;
  int nslices;
  ck_slice_t slices[CK_MAX_SLICES];
} opts_t;

static int parse_args(int argc, char **argv, opts_t *o, ck_result_t *r)
{
  memset(o, 0, sizeof *o);
  o->progress_interval = 2.0;
  r->max_ratio = r->min_facet_angle = r->max_hausdorff = r->max_volume_error = NAN;
  r->min_dihedral = r->max_dihedral = NAN;
  r->max_mesh_to_image = r->max_p99 = NAN;
  r->facet_exceptions = 0;
  r->volume_min_voxels = 10000;
  r->require_labels = -1;
  r->require_whole = -1;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
      fputs(USAGE, stdout);
      return 0;
    }
    if (strcmp(a, "--json") == 0) {
      o->json = 1;
      continue;
    }
    if (strcmp(a, "--no-distances") == 0) {
      o->no_distances = 1;
      continue;
    }
    if (strcmp(a, "--allow-external-data") == 0) {
      o->allow_external_data = 1;
      continue;
    }
    if (strcmp(a, "--quiet") == 0) {
      o->quiet = 1;
      continue;
    }
    if (a[0] == '-' && a[1] == '-') {
      if (i + 1 >= argc) return fail_usage("option %s needs a value", a);
      const char *val = argv[++i];
      double v;
      if (strcmp(a, "--image") == 0) {
        o->image = val;
        continue;
      }
      if (strcmp(a, "--plot") == 0) {
        o->plot = val;
        continue;
      }
      if (strcmp(a, "--slice") == 0) {
        char why[256];
        if (o->nslices == CK_MAX_SLICES) return fail_usage("at most %s --slice options", "16");
        if (!ck_slice_parse(val, &o->slices[o->nslices++], why, sizeof why)) return fail_usage("%s", why);
        continue;
      }
      if (strcmp(a, "--progress-interval") == 0) {
        if (!parse_num(val, &o->progress_interval) || o->progress_interval < 0)
          return fail_usage("bad value for %s", a);
        continue;
      }
      if (!parse_num(val, &v) || v < 0) return fail_usage("bad value for %s", a);
      if (strcmp(a, "--max-ratio") == 0)
        r->max_ratio = v;
      else if (strcmp(a, "--min-facet-angle") == 0)
        r->min_facet_angle = v;
      else if (strcmp(a, "--min-dihedral") == 0 && v <= 180)
        r->min_dihedral = v;
      else if (strcmp(a, "--max-dihedral") == 0 && v <= 180)
        r->max_dihedral = v;
      else if (strcmp(a, "--min-dihedral") == 0 || strcmp(a, "--max-dihedral") == 0)
        return fail_usage("%s takes an angle of 0..180 degrees", a);
      else if (strcmp(a, "--facet-angle-exceptions") == 0)
        r->facet_exceptions = v;
      else if (strcmp(a, "--max-hausdorff") == 0)
        r->max_hausdorff = v;
      else if (strcmp(a, "--max-mesh-to-image") == 0)
        r->max_mesh_to_image = v;
      else if (strcmp(a, "--max-p99") == 0)
        r->max_p99 = v;
      else if (strcmp(a, "--max-volume-error") == 0)
        r->max_volume_error = v;
      else if (strcmp(a, "--volume-min-voxels") == 0)
        r->volume_min_voxels = (int64_t)v;
      else if (strcmp(a, "--require-labels") == 0)
        r->require_labels = (int64_t)v;
      else if (strcmp(a, "--require-whole") == 0)
        r->require_whole = (int64_t)v;
      else
        return fail_usage("unknown option %s", a);
      continue;
    }
    if (o->mesh) return fail_usage("more than one mesh given (%s)", a);
    o->mesh = a;
  }
  if (!o->mesh) return fail_usage("%s", "no mesh file given");
  if (o->nslices && !o->plot) return fail_usage("%s", "--slice needs --plot DIR");
  if (!o->image && (!isnan(r->max_hausdorff) || !isnan(r->max_volume_error) || r->require_labels >= 0 || r->require_whole >= 0 ||
                    !isnan(r->max_mesh_to_image) || !isnan(r->max_p99)))
    return fail_usage("%s", "the fidelity thresholds (--max-hausdorff, --max-mesh-to-image, --max-p99, "
                            "--max-volume-error, --require-labels, --require-whole) need --image");
  if (o->no_distances && (!isnan(r->max_hausdorff) || !isnan(r->max_mesh_to_image) || !isnan(r->max_p99)))
    return fail_usage("%s", "--no-distances leaves no distance to hold to --max-hausdorff, --max-mesh-to-image or --max-p99");
  return -1;
}

static void violation(ck_result_t *r, const char *fmt, double a, double b, double c)
{
  if (r->nviol >= CK_MAX_VIOL) return;
  snprintf(r->viol[r->nviol++], sizeof r->viol[0], fmt, a, b, c);
}

static void thresholds(ck_result_t *r)
{
  const ck_quality_t *q = &r->quality;
  if (!r->have_quality) return;
  if (!isnan(r->max_ratio) && q->ratio_above_bound > 0)
    violation(r, "max-ratio: %.0f tetrahedra have a radius-edge ratio above %g (max %.4g)",
              (double)q->ratio_above_bound, r->max_ratio, q->max_ratio);
  if (!isnan(r->min_dihedral) && !ck_meets_min(q->min_dihedral, r->min_dihedral)) /* (NaN fails) */
    violation(r, "min-dihedral: the smallest dihedral angle is %.4g deg (bound %g deg; %.0f tets below 15 deg)",
              q->min_dihedral, r->min_dihedral, (double)q->dihedral_below[2]);
  if (!isnan(r->max_dihedral) && !ck_meets_max(q->max_dihedral, r->max_dihedral))
    violation(r, "max-dihedral: the largest dihedral angle is %.4g deg (bound %g deg; %.0f tets above 160 deg)",
              q->max_dihedral, r->max_dihedral, (double)q->dihedral_above[0]);
  if (!isnan(r->min_facet_angle)) {
    double frac = q->ntri ? (double)q->planar_below_bound / (double)q->ntri : 0;
    if (frac > r->facet_exceptions)
      violation(r, "min-facet-angle: %.0f interface triangles (fraction %.3g) have an angle below %g",
                (double)q->planar_below_bound, frac, r->min_facet_angle);
  }
  if (!r->have_fidelity) return;
  const ck_fidelity_t *f = &r->fidelity;
  if (!isnan(r->max_hausdorff) && !(f->two_sided.max <= r->max_hausdorff))
    violation(r, "max-hausdorff: two-sided distance %.4g mm exceeds %g mm", f->two_sided.max,
              r->max_hausdorff, 0);
  if (!isnan(r->max_mesh_to_image) && !(f->mesh_to_image.max <= r->max_mesh_to_image))
    violation(r, "max-mesh-to-image: a mesh interface point lies %.4g mm from the image's interfaces (bound %g mm)",
              f->mesh_to_image.max, r->max_mesh_to_image, 0);
  if (!isnan(r->max_p99) && !(f->two_sided.p99 <= r->max_p99))
    violation(r, "max-p99: the 99th percentile of the two-sided distance is %.4g mm (bound %g mm)", f->two_sided.p99,
              r->max_p99, 0);
  for (int i = 0; i < f->nlabels; i++) {
    const ck_label_t *L = &f->labels[i];
    if (!isnan(r->max_volume_error) && L->voxels >= r->volume_min_voxels &&
        !(fabs(L->rel_error_pct) <= r->max_volume_error))
      violation(r, "max-volume-error: label %.0f volume error %.3f%% exceeds %g%%", (double)L->value,
                L->rel_error_pct, r->max_volume_error);
    if (r->require_labels >= 0 && L->in_image && L->voxels >= r->require_labels && !L->in_mesh)
      violation(r, "require-labels: label %.0f (%.0f voxels) is missing from the mesh",
                (double)L->value, (double)L->voxels, 0);
  }
  for (int64_t k = 0; r->require_whole >= 0 && k < f->ncomponents; k++) {
    const ck_component_t *c = &f->components[k];
    if (c->voxels >= r->require_whole && c->pieces != 1)
      violation(r, "require-whole: label %.0f: an image component of %.0f voxels is %.0f pieces in the mesh",
                (double)c->value, (double)c->voxels, (double)c->pieces);
  }
}

static int run(const opts_t *o, ck_result_t *r)
{
  ck_mesh_t m;
  ck_topo_t topo;
  i2m_image_t *img = NULL;
  double t0 = i2m_wtime();
  int code = 2;
  memset(&topo, 0, sizeof topo);
  ck_progress_t pr;
  ck_progress_begin(&pr, "reading the mesh", "bytes", 0);
  if (ck_mesh_read_progress(o->mesh, &m, &pr) != I2M_OK) {
    fprintf(stderr, "i2m-check: %s\n", i2m_error_message());
    return 2;
  }
  const i2m_image_read_opts_t ro = {.allow_external_data = o->allow_external_data != 0};
  ck_progress_set(&pr, pr.p.total);
  ck_progress_end(&pr);
  ck_progress_begin(&pr, "reading the image", "voxels", 0);
  if (o->image && i2m_image_read_with(o->image, &ro, &img, NULL) != I2M_OK) {
    fprintf(stderr, "i2m-check: %s\n", i2m_error_message());
    goto done;
  }
  if (img) {
    ck_progress_set(&pr, img->n[0] * img->n[1] * img->n[2]);
    ck_progress_end(&pr);
  }
  if (ck_slice_check(&m, img, o->slices, o->nslices) != I2M_OK) {
    fprintf(stderr, "i2m-check: %s\n", i2m_error_message());
    goto done;
  }
  r->mesh = &m;
  r->img = img;
  r->t_read = i2m_wtime() - t0;
  double t = i2m_wtime();
  ck_progress_begin(&pr, "validity", "tet passes", 0);
  if (ck_validity_progress(&m, &r->validity, &topo, &pr) != I2M_OK) goto fail;
  if (ck_stitch_check(&m, &topo, &r->validity) != I2M_OK) goto fail;
  ck_progress_end(&pr);
  r->t_validity = i2m_wtime() - t;
  if (!r->validity.bad_index && !r->validity.nonfinite && m.nt > 0) {
    t = i2m_wtime();
    double rb = isnan(r->max_ratio) ? 2.0 : r->max_ratio;
    double fb = isnan(r->min_facet_angle) ? 30.0 : r->min_facet_angle;
    if (ck_quality(&m, &topo, rb, fb, &r->quality) != I2M_OK) goto fail;
    r->have_quality = 1;
    r->t_quality = i2m_wtime() - t;
    if (img) {
      t = i2m_wtime();
      if (ck_fidelity(&m, &topo, img, !o->no_distances, &r->fidelity) != I2M_OK) goto fail;
      ck_fidelity_whole(&r->fidelity, r->require_whole >= 0 ? r->require_whole : CK_WHOLE_DEFAULT);
      r->have_fidelity = 1;
      r->t_fidelity = i2m_wtime() - t;
    }
  }
  thresholds(r);
  if (o->plot && r->have_quality) {
    mkdir(o->plot, 0777);
    if (ck_plot(o->plot, &m, &r->quality, img, o->slices, o->nslices) != I2M_OK) goto fail;
  }
  r->t_total = i2m_wtime() - t0;
  if (o->json)
    ck_report_json(stdout, r);
  else
    ck_report_text(stdout, r);
  fflush(stdout);
  code = r->validity.valid && r->nviol == 0 ? 0 : 1;
  goto done;
fail:
  fprintf(stderr, "i2m-check: %s\n", i2m_error_message());
  code = 2;
done:
  if (r->have_fidelity) ck_fidelity_free(&r->fidelity);
  ck_topo_free(&topo);
  ck_mesh_free(&m);
  i2m_image_destroy(&img);
  return code;
}

int main(int argc, char **argv)
{
  opts_t o;
  ck_result_t r;
  i2m_malloc_tune();
  i2m_outfile_signals();
  memset(&r, 0, sizeof r);
  int c = parse_args(argc, argv, &o, &r);
  if (c >= 0) return c;
  i2m_log_set_level(o.quiet ? I2M_LOG_WARN : I2M_LOG_INFO); /* INFO: the progress lines */
  ck_progress_set_interval(o.progress_interval);
  r.mesh_path = o.mesh;
  r.image_path = o.image;
  return run(&o, &r);
}
