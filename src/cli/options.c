/* cli layer: parsing and validation of bin/i2m's options (one clear message per mistake). */
#include <ctype.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "i2m/dt.h"
#include "i2m/io.h"
#include "options.h"

void cli_usage(FILE *f)
{
  fprintf(f,
          "usage: i2m INPUT -o OUTPUT [options]\n"
          "Meshes a segmented 3D image (every voxel a tissue label) into a conforming tetrahedral mesh.\n"
          "  INPUT                 .nrrd .nhdr .nii .nii.gz .mha .mhd .inr .inr.gz\n"
          "  -o, --output FILE     .vtu (VTK), .pvtu (VTK pieces: one per MPI rank), .mesh (Medit) or .msh (Gmsh);\n"
          "                        a .vtu (.pvtu) comes with FILE.interfaces.vtu (.pvtu): the interface triangles\n"
          "  --vtu-raw             VTU data not compressed (default: zlib)\n"
          "  --msh-format V        Gmsh file version: 4.1 (default) or 2.2 (.msh output only)\n"
          "  --ascii               a text Gmsh file instead of binary (.msh output only)\n"
          "  --delta D             surface sampling / fidelity distance in mm (default: max(0.8 x smallest spacing, 0.5 x largest))\n"
          "  --ratio R             radius-edge bound, >= 2 (default 2)\n"
          "  --facet-angle A       minimum planar angle of interface triangles, <= 30 degrees (default 30)\n"
          "  --size S              maximum circumradius in mm (default none)\n"
          "  --size-label L=S      maximum circumradius S for the tets of label L (repeatable)\n"
          "  --region X0,Y0,Z0,X1,Y1,Z1:S[:R]\n"
          "                        a world box (mm) whose tets get size S and ratio R (repeatable)\n"
          "  --threads T           worker threads (default: OMP_NUM_THREADS if set, else the cores\n"
          "                        the process may use)\n"
          "  --coarse-factor F     a coarse mesh first, at F x delta and F x the size bounds (default 4)\n"
          "  --no-pin              do not bind the threads to cores\n"
          "  --sliver-angle A      after refinement, insert points into (or move the vertices of) the\n"
          "                        tets whose smallest dihedral angle is below A degrees (0-30;\n"
          "                        default 0: off)\n"
          "  --deterministic       the same mesh whatever the number of threads and ranks (subregions\n"
          "                        refined in turn instead of speculation with vertex locks)\n"
          "  --depth D             the octree of 8^D subregions that ranks (and the deterministic\n"
          "                        mode) refine in turn (default: from the ranks, threads and mesh size)\n"
          "  --report FILE.json    write the run report as JSON\n"
          "  --trace FILE          under MPI: one line per task (rank, subregion, start, end, bytes in and\n"
          "                        out, tets made), for replaying or simulating the run\n"
          "  --seed N              random seed (default 1)\n"
          "  --check               check the triangulation's validity before writing (slow)\n"
          "  --max-memory BYTES    refuse a run whose estimated peak memory (per process) exceeds this\n"
          "                        (8G, 500M; default: the machine's memory and the process limits)\n"
          "  --allow-external-data a detached header (.nhdr, .mhd) may name a data file outside its\n"
          "                        own directory (refused by default)\n"
          "  --quiet               no progress or summary (errors only); --verbose: more detail\n"
          "  -h, --help            this help\n");
}

static i2m_err_t parse_double(const char *opt, const char *s, double *x)
{
  char *end = NULL;
  errno = 0;
  double v = s ? strtod(s, &end) : NAN;
  I2M_CHECK(s && end != s && *end == '\0' && errno == 0 && isfinite(v), I2M_ERR_ARG,
            "%s expects a number, got '%s'", opt, s ? s : "(nothing)");
  *x = v;
  return I2M_OK;
}

static i2m_err_t parse_int(const char *opt, const char *s, long long *x)
{
  char *end = NULL;
  errno = 0;
  long long v = s ? strtoll(s, &end, 10) : 0;
  I2M_CHECK(s && end != s && *end == '\0' && errno == 0, I2M_ERR_ARG, "%s expects an integer, got '%s'", opt,
            s ? s : "(nothing)");
  *x = v;
  return I2M_OK;
}

static i2m_err_t parse_label_size(const char *s, cli_options_t *o, int *n)
{
  I2M_CHECK(*n < I2M_MAX_LIST, I2M_ERR_ARG, "--size-label: at most %d are supported", I2M_MAX_LIST);
  const char *eq = s ? strchr(s, '=') : NULL;
  I2M_CHECK(eq, I2M_ERR_ARG, "--size-label expects LABEL=SIZE, got '%s'", s ? s : "(nothing)");
  char label[64];
  size_t len = (size_t)(eq - s);
  I2M_CHECK(len > 0 && len < sizeof label, I2M_ERR_ARG, "--size-label expects LABEL=SIZE, got '%s'", s);
  memcpy(label, s, len);
  label[len] = '\0';
  long long v = 0;
  I2M_CALL(parse_int("--size-label (label)", label, &v));
  o->label_sizes[*n].value = v;
  I2M_CALL(parse_double("--size-label (size)", eq + 1, &o->label_sizes[*n].size));
  I2M_CHECK(o->label_sizes[*n].size > 0, I2M_ERR_ARG, "--size-label %s: the size must be positive", s);
  (*n)++;
  return I2M_OK;
}

/* "8G", "500M", "1.5T", "123456" (bytes; K M G T binary). */
static i2m_err_t parse_bytes(const char *opt, const char *s, double *x)
{
  static const char units[] = "KMGT";
  char *end = NULL;
  errno = 0;
  const double v = s ? strtod(s, &end) : NAN;
  const char *u = end && *end ? strchr(units, toupper((unsigned char)*end)) : NULL;
  const double unit = u ? ldexp(1.0, 10 * (int)(u - units + 1)) : 1.0;
  const char *rest = u ? end + 1 : end; /* (after the unit, an optional B) */
  if (u && (*rest == 'B' || *rest == 'b')) rest++;
  I2M_CHECK(s && end != s && *rest == '\0' && errno == 0 && isfinite(v) && v > 0, I2M_ERR_ARG,
            "%s expects a size in bytes such as 8G, 500M or 1.5T, got '%s'", opt, s ? s : "(nothing)");
  *x = v * unit;
  return I2M_OK;
}

static i2m_err_t parse_region(const char *s, cli_options_t *o, int *n)
{
  I2M_CHECK(*n < I2M_MAX_LIST, I2M_ERR_ARG, "--region: at most %d are supported", I2M_MAX_LIST);
  I2M_CHECK(s, I2M_ERR_ARG, "--region expects X0,Y0,Z0,X1,Y1,Z1:SIZE[:RATIO]");
  i2m_region_t *g = &o->regions[*n];
  double c[6];
  char tail[256] = "";
  int used = 0;
  int got = sscanf(s, "%lf,%lf,%lf,%lf,%lf,%lf:%n", &c[0], &c[1], &c[2], &c[3], &c[4], &c[5], &used);
  I2M_CHECK(got == 6 && used > 0, I2M_ERR_ARG, "--region expects X0,Y0,Z0,X1,Y1,Z1:SIZE[:RATIO], got '%s'", s);
  for (int a = 0; a < 6; a++)
    I2M_CHECK(isfinite(c[a]), I2M_ERR_ARG, "--region %s: the corners must be finite numbers", s);
  I2M_CHECK(strlen(s + used) < sizeof tail, I2M_ERR_ARG, "--region %s: SIZE[:RATIO] is too long", s);
  snprintf(tail, sizeof tail, "%s", s + used);
  char *colon = strchr(tail, ':');
  g->ratio = o->params.ratio;
  if (colon) {
    *colon = '\0';
    I2M_CALL(parse_double("--region (ratio)", colon + 1, &g->ratio));
  }
  I2M_CALL(parse_double("--region (size)", tail, &g->size));
  for (int a = 0; a < 3; a++) {
    g->lo[a] = fmin(c[a], c[a + 3]);
    g->hi[a] = fmax(c[a], c[a + 3]);
    I2M_CHECK(g->lo[a] < g->hi[a], I2M_ERR_ARG, "--region %s: the box is empty along axis %d", s, a);
  }
  I2M_CHECK(g->size > 0, I2M_ERR_ARG, "--region %s: the size must be positive", s);
  (*n)++;
  return I2M_OK;
}

/* The options that take a value (parse_valued reads each). */
static bool takes_value(const char *opt)
{
  static const char *const names[] = {"-o", "--output", "--report", "--trace", "--delta", "--ratio", "--facet-angle",
                                      "--size", "--size-label", "--region", "--seed", "--coarse-factor", "--max-memory",
                                      "--sliver-angle", "--depth", "--threads", "--msh-format"};
  for (size_t k = 0; k < sizeof names / sizeof *names; k++)
    if (!strcmp(opt, names[k])) return true;
  return false;
}

/* Options that take a value. */
static i2m_err_t parse_valued(const char *opt, const char *val, cli_options_t *o, int *nls, int *nrg)
{
  i2m_refine_params_t *p = &o->params;
  long long iv = 0;
  if (!strcmp(opt, "-o") || !strcmp(opt, "--output")) o->output = val;
  else if (!strcmp(opt, "--report")) o->report = val;
  else if (!strcmp(opt, "--trace")) o->trace = val;
  else if (!strcmp(opt, "--delta")) {
    I2M_CALL(parse_double(opt, val, &p->delta));
    I2M_CHECK(p->delta > 0, I2M_ERR_ARG, "--delta must be a positive length in mm (got %s)", val);
  } else if (!strcmp(opt, "--ratio")) I2M_CALL(parse_double(opt, val, &p->ratio));
  else if (!strcmp(opt, "--facet-angle")) I2M_CALL(parse_double(opt, val, &p->facet_angle));
  else if (!strcmp(opt, "--size")) {
    I2M_CALL(parse_double(opt, val, &p->size));
    I2M_CHECK(p->size > 0, I2M_ERR_ARG, "--size must be a positive length in mm (got %s)", val);
  } else if (!strcmp(opt, "--size-label")) I2M_CALL(parse_label_size(val, o, nls));
  else if (!strcmp(opt, "--region")) I2M_CALL(parse_region(val, o, nrg));
  else if (!strcmp(opt, "--max-memory")) I2M_CALL(parse_bytes(opt, val, &o->max_memory));
  else if (!strcmp(opt, "--seed")) {
    I2M_CALL(parse_int(opt, val, &iv));
    p->seed = (uint64_t)iv;
  } else if (!strcmp(opt, "--coarse-factor")) {
    I2M_CALL(parse_double(opt, val, &o->coarse_factor));
    I2M_CHECK(o->coarse_factor >= 1, I2M_ERR_ARG, "--coarse-factor must be at least 1 (got %s)", val);
  } else if (!strcmp(opt, "--sliver-angle")) {
    I2M_CALL(parse_double(opt, val, &o->sliver_angle));
    I2M_CHECK(o->sliver_angle >= 0 && o->sliver_angle <= 30, I2M_ERR_ARG,
              "--sliver-angle must be between 0 and 30 degrees (got %s)", val);
  } else if (!strcmp(opt, "--depth")) {
    I2M_CALL(parse_int(opt, val, &iv));
    I2M_CHECK(iv >= 1 && iv <= 6, I2M_ERR_ARG, "--depth must be between 1 and 6 (8^depth subregions; got %s)", val);
    o->depth = (int)iv;
  } else if (!strcmp(opt, "--threads")) {
    I2M_CALL(parse_int(opt, val, &iv));
    I2M_CHECK(iv >= 1 && iv <= I2M_DT_MAX_OWNERS, I2M_ERR_ARG, "--threads must be between 1 and %u (got %s)",
              I2M_DT_MAX_OWNERS, val);
    o->threads = (int)iv;
  } else if (!strcmp(opt, "--msh-format")) {
    I2M_CHECK(!strcmp(val, "4.1") || !strcmp(val, "2.2"), I2M_ERR_ARG, "--msh-format must be 4.1 or 2.2 (got %s)", val);
    o->msh_version = !strcmp(val, "4.1") ? 41 : 22;
  } else return I2M_ERROR(I2M_ERR_ARG, "unknown option '%s' (see i2m --help)", opt);
  return I2M_OK;
}

/* The files a run writes are not the input nor one another (compared as files, not as
 * strings), and the report is JSON: a slip of the keyboard must not replace a segmentation
 * or a mesh.  interfaces: the companion file of a .vtu or .pvtu output, or NULL. */
static i2m_err_t check_paths(const cli_options_t *o, const char *interfaces)
{
  char side[4096]; /* a Medit mesh's JSON side file */
  const bool has_side = i2m_mesh_side_path(o->output, side, sizeof side);
  const struct {
    const char *opt, *path;
  } f[] = {{"the input", o->input},
           {"-o", o->output},
           {"--report", o->report},
           {"--trace", o->trace},
           {"the interfaces file of -o", interfaces},
           {"the Medit side file", has_side ? side : NULL}};
  const size_t n = sizeof f / sizeof *f;
  for (size_t i = 0; i < n; i++)
    for (size_t j = i + 1; j < n; j++)
      I2M_CHECK(!f[i].path || !f[j].path || !i2m_same_file(f[i].path, f[j].path), I2M_ERR_ARG,
                "%s and %s name the same file (%s)", f[i].opt, f[j].opt, f[j].path);
  if (o->report) {
    const size_t len = strlen(o->report);
    I2M_CHECK(len > 5 && strcasecmp(o->report + len - 5, ".json") == 0, I2M_ERR_ARG,
              "--report %s: the report is JSON, its name must end in .json", o->report);
  }
  return I2M_OK;
}

i2m_err_t cli_parse(int argc, char **argv, cli_options_t *o)
{
  memset(o, 0, sizeof *o);
  i2m_refine_params_default(&o->params);
  o->coarse_factor = 4.0;
  int nls = 0, nrg = 0;
  for (int i = 1; i < argc; i++) {
    const char *a = argv[i];
    if (!strcmp(a, "-h") || !strcmp(a, "--help")) o->help = 1;
    else if (!strcmp(a, "--version")) o->version = 1;
    else if (!strcmp(a, "--quiet") || !strcmp(a, "-q")) o->quiet = 1;
    else if (!strcmp(a, "--verbose") || !strcmp(a, "-v")) o->verbose = 1;
    else if (!strcmp(a, "--check")) o->check = 1;
    else if (!strcmp(a, "--no-pin")) o->no_pin = 1;
    else if (!strcmp(a, "--deterministic")) o->deterministic = 1;
    else if (!strcmp(a, "--allow-external-data")) o->allow_external_data = 1;
    else if (!strcmp(a, "--ascii")) o->ascii = 1;
    else if (!strcmp(a, "--vtu-raw")) o->vtu_raw = 1;
    else if (a[0] == '-' && a[1] != '\0') {
      I2M_CHECK(takes_value(a), I2M_ERR_ARG, "unknown option '%s' (see i2m --help)", a);
      I2M_CHECK(i + 1 < argc, I2M_ERR_ARG, "option %s needs a value (see i2m --help)", a);
      I2M_CALL(parse_valued(a, argv[i + 1], o, &nls, &nrg));
      i++;
    } else {
      I2M_CHECK(!o->input, I2M_ERR_ARG, "more than one input image given ('%s' and '%s')", o->input, a);
      o->input = a;
    }
  }
  o->params.nlabel_sizes = nls;
  o->params.label_sizes = o->label_sizes;
  o->params.nregions = nrg;
  o->params.regions = o->regions;
  if (o->help || o->version) return I2M_OK;
  I2M_CHECK(o->input, I2M_ERR_ARG, "no input image given (usage: i2m INPUT -o OUTPUT; see i2m --help)");
  I2M_CHECK(o->output, I2M_ERR_ARG, "no output file given: add -o OUTPUT.vtu, .mesh or .msh");
  I2M_CALL(i2m_mesh_check_writable(o->output));
  I2M_CHECK((!o->msh_version && !o->ascii) || i2m_format_from_path(o->output) == I2M_FORMAT_GMSH, I2M_ERR_ARG,
            "%s applies to Gmsh output only (-o %s is not a .msh file)", o->msh_version ? "--msh-format" : "--ascii",
            o->output);
  char interfaces[4096];
  const bool companion = i2m_mesh_interfaces_path(o->output, interfaces, sizeof interfaces);
  if (companion) I2M_CALL(i2m_mesh_check_writable(interfaces));
  return check_paths(o, companion ? interfaces : NULL);
}
