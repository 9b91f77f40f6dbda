/* i2m-check (tools/check): an independent checker of written meshes.  It reads a mesh file
 * (VTU, Medit, Gmsh 4.1 or 2.2, or the pieces of a .pvtu stitched by global id), recomputes
 * validity, quality and, with the image, fidelity, with its own geometry code (it never uses
 * src/geom or src/delaunay: it must not share a bug with the mesher).  From libi2m it uses
 * only the base utilities and the image layer (reader, connected components).
 *
 * Files: read_mesh.c (the formats), pvtu.c (pieces stitched, seams checked), ck_geom.c
 * (exact orientation, distances, angles, a grid of buckets), validity.c (indices,
 * orientation, face matching, vertices, interface triangles), quality.c, fidelity.c (image
 * interfaces, two-sided distances, volumes, components), plot.c (SVG), report.c (text and
 * JSON), check_main.c (options, thresholds, exit code). */
#ifndef I2M_CHECK_H
#define I2M_CHECK_H

#include "i2m/base.h"
#include "i2m/image.h"

#include <math.h>
#include <stdatomic.h>
#include <stdio.h>

#define CK_PI 3.14159265358979323846

/* A bound is met to within rounding.  The mesher tests a bound in its own frame (world
 * coordinates minus a shift) with products of squared lengths; the checker measures the
 * figure again in world coordinates with sqrt and acos, a few ulps away.  A facet the mesher
 * kept at exactly 30 degrees reads 29.999999999999996 here (seen on the spine), so a figure
 * within CK_BOUND_SLACK (relative) of its bound meets it.  NaN meets no bound. */
#define CK_BOUND_SLACK 1e-12
static inline int ck_meets_min(double v, double bound) { return v >= bound - fabs(bound) * CK_BOUND_SLACK; }
static inline int ck_meets_max(double v, double bound) { return v <= bound + fabs(bound) * CK_BOUND_SLACK; }

/* ---- the mesh as read from the file ---- */
/* ---- loops on OpenMP threads ---- */
#ifdef _OPENMP
#define CK_OMP(x) _Pragma(x)
#else
#define CK_OMP(x)
#endif
/* The passes over the tets whose figures are sums or first extremes cut their range into
 * CK_CHUNKS fixed chunks, run on any threads, and combine the chunks' figures in chunk order:
 * the figures do not depend on the number of threads. */
#define CK_CHUNKS 256
static inline int64_t ck_chunk_begin(int64_t n, int c) { return n * c / CK_CHUNKS; }

/* ---- progress lines of the long phases (progress.c) ---- */
typedef struct {
  i2m_progress_t p;
  _Atomic int64_t done; /* work done so far, added by any thread */
} ck_progress_t;
/** The interval between two lines of one phase, in seconds (2 by default; 0: every update). */
void ck_progress_set_interval(double seconds);
/** Starts a phase of @p total units (0: unknown). */
void ck_progress_begin(ck_progress_t *p, const char *phase, const char *unit, int64_t total);
/** Adds @p n units done; cheap: call it per chunk of work, from any thread (thread 0 prints). */
void ck_progress_add(ck_progress_t *p, int64_t n);
/** Sets the units done (no line): for a phase whose count is known only at its end. */
void ck_progress_set(ck_progress_t *p, int64_t done);
/** Sets the units done and prints if the interval has passed: for a loop run by one thread. */
void ck_progress_to(ck_progress_t *p, int64_t done);
/** The closing line ("phase done: ...") when the phase lasted at least the interval. */
void ck_progress_end(ck_progress_t *p);

typedef struct ck_stitch ck_stitch_t;

typedef struct {
  char format[8];     /* "vtu", "pvtu", "medit", "gmsh" */
  const char *path;   /* borrowed: the file name, for messages */
  int64_t nv;
  double *xyz;        /* owned: [nv][3] world coordinates */
  int64_t nt;
  int64_t *tet;       /* owned: [nt][4] 0-based vertex ids as found (may be out of range) */
  int64_t *tet_label; /* owned: [nt] material */
  int has_tri;        /* the file has interface triangles (Medit, Gmsh) */
  int tri_labels_known; /* every file triangle's label pair is known */
  int64_t ntri;
  int64_t *tri;       /* owned: [ntri][3] 0-based vertex ids */
  int64_t *tri_label; /* owned: [ntri][2] label pair (a <= b), valid if tri_labels_known */
  int64_t ignored_cells; /* cells of other kinds skipped by the reader */
  int has_gid;        /* a VTU file with the point data GlobalNodeId */
  int64_t *gid;       /* owned: [nv] GlobalNodeId (VTU with has_gid; a .pvtu: -1 for the
                         vertices of pieces without ids) */
  ck_stitch_t *stitch; /* owned: how a .pvtu's pieces were stitched; NULL for one file */
} ck_mesh_t;

/** Reads a mesh file (format by extension, .vtu .mesh .msh).  On error the message names the
 *  file and the problem; *m is left empty. */
i2m_err_t ck_mesh_read(const char *path, ck_mesh_t *m);
/** The same with a progress line of the bytes parsed (@p pr begun by the caller; its total is
 *  set to the file's size; NULL: none). */
i2m_err_t ck_mesh_read_progress(const char *path, ck_mesh_t *m, ck_progress_t *pr);
void ck_mesh_free(ck_mesh_t *m);

/* ---- a distributed mesh (.pvtu): pieces stitched by global id (pvtu.c) ---- */
#define CK_STITCH_MSG 512
struct ck_stitch {
  int npieces;
  char **piece_path;    /* owned: [npieces] piece files, relative to the working directory */
  int64_t *piece_nv;    /* owned: [npieces] vertices of each piece */
  int64_t *tet_start;   /* owned: [npieces + 1] piece p's tets are tet_start[p] .. [p+1]-1 of
                           the stitched mesh, in the piece's order */
  int8_t *piece_has_gid; /* owned: [npieces] */
  int32_t *vert_pieces; /* owned: [nv] pieces holding each stitched vertex */
  int64_t vertices_before, seam_vertices; /* seam: a global id seen in 2+ pieces */
  /* errors (each makes the stitched mesh invalid) and the first of each kind */
  int64_t coordinate_mismatches; /* (a) one global id, different coordinates */
  int64_t shared_points;         /* (b) two global ids at one point */
  int64_t pieces_without_ids;    /* (c) a piece without GlobalNodeId */
  int seams_checked;             /* the faces below were looked for */
  int64_t seam_boundary_faces;   /* boundary faces with three seam vertices */
  int64_t one_sided_faces;       /* (d) ... whose outer side another piece meshes */
  char first_mismatch[CK_STITCH_MSG], first_shared[CK_STITCH_MSG], first_without_ids[CK_STITCH_MSG],
      first_one_sided[CK_STITCH_MSG];
};

/** Reads a .pvtu: every piece with ck_mesh_read, stitched into *m by GlobalNodeId; m->stitch
 *  records the pieces and the stitching errors (a)-(c).  A piece that cannot be read (a
 *  missing file) is an error naming it. */
i2m_err_t ck_pvtu_read(const char *path, ck_mesh_t *m);
/** The piece files a .pvtu names (owned: free with ck_pvtu_pieces_free), resolved relative to
 *  its directory. */
i2m_err_t ck_pvtu_pieces(const char *path, char ***pieces, int *npieces);
void ck_pvtu_pieces_free(char ***pieces, int npieces);
void ck_stitch_free(ck_stitch_t **st);

/* ---- interface triangles derived from the tetrahedra ---- */
typedef struct {
  int64_t n;
  int32_t *v;   /* owned: [n][3] vertices, oriented outward: the normal points from the
                   higher label to the lower (the background 0 ranks lowest), out of the mesh
                   on its outer boundary */
  int64_t *lab; /* owned: [n][2] label pair, lab[2i] < lab[2i+1]; 0 = outside the mesh */
} ck_iface_t;

/* ---- validity ---- */
typedef struct {
  int valid;
  int64_t bad_index, first_bad_index;   /* tets with a vertex id out of range */
  int64_t tri_bad_index;                /* file triangles with an id out of range */
  int64_t nonfinite, first_nonfinite;   /* vertices with a NaN or infinite coordinate */
  int64_t inverted, first_inverted;     /* exact negative orientation */
  int64_t degenerate, first_degenerate; /* exact zero volume */
  double min_volume, total_volume;
  int64_t min_volume_tet;
  int64_t interior_faces, boundary_faces;
  int64_t nonmanifold_faces, first_nonmanifold_tet; /* faces of 3+ tets */
  int64_t overlapping_faces, first_overlapping_tet; /* two positive tets on one side */
  int64_t dangling, first_dangling;
  int64_t duplicate, first_duplicate, first_duplicate_of;
  int64_t boundary_edges, boundary_open_edges;
  int64_t interface_triangles, interface_pairs;
  /* comparison of the file's triangles with the derived ones */
  int64_t file_triangles, file_not_interface, interface_not_in_file, file_label_mismatch,
      file_duplicate;
  int64_t file_outward, file_inward; /* matched file triangles oriented each way */
  int64_t file_flipped;              /* those against the file's majority (mixed: invalid) */
  char errors[512]; /* comma-separated defect names */
} ck_validity_t;

/* Results of validity needed later (owned; freed with ck_topo_free). */
typedef struct {
  int64_t *nb;        /* [nt][4] 4*t'+f' across the face opposite vertex f; -1 boundary;
                         -2 face of 3+ tets */
  double *vol;        /* [nt] signed volume */
  ck_iface_t iface;
} ck_topo_t;

i2m_err_t ck_validity(const ck_mesh_t *m, ck_validity_t *v, ck_topo_t *topo);
/** The same with a progress line (@p pr begun by the caller, its total set here: the tets
 *  times the passes; NULL: none). */
i2m_err_t ck_validity_progress(const ck_mesh_t *m, ck_validity_t *v, ck_topo_t *topo, ck_progress_t *pr);
void ck_topo_free(ck_topo_t *t);
/** The orientation of the file's interface triangles: "outward" (normals from the higher
 *  label to the lower, out of the domain on the outer boundary), "inward", "mixed" (both:
 *  invalid) or "none" (no file triangle matched). */
const char *ck_validity_orientation(const ck_validity_t *v);
/** Appends a defect name to v->errors and marks the mesh invalid. */
void ck_validity_add_error(ck_validity_t *v, const char *name);
/** For a stitched mesh (m->stitch): looks for faces seen by one side only (d, with the face
 *  adjacency of @p topo when validity computed it) and adds every stitching error to @p v. */
i2m_err_t ck_stitch_check(const ck_mesh_t *m, const ck_topo_t *topo, ck_validity_t *v);

/* ---- quality ---- */
#define CK_HIST_BINS 180
typedef struct {
  double min_dihedral, max_dihedral; /* degrees */
  int64_t min_dihedral_tet, max_dihedral_tet;
  int64_t dihedral_hist[CK_HIST_BINS];
  int64_t dihedral_below[4]; /* tets with a dihedral angle < 5, 10, 15, 20 degrees */
  int64_t dihedral_above[2]; /* tets with a dihedral angle > 160, 170 degrees */
  double max_ratio;          /* circumradius / shortest edge */
  int64_t max_ratio_tet;
  double ratio_p50, ratio_p90, ratio_p99, ratio_p999, ratio_mean;
  double ratio_bound;        /* bound used for the count below */
  int64_t ratio_above_bound, ratio_above_2;
  double min_planar_angle;   /* degrees, over interface triangles */
  int64_t min_planar_tri;
  double facet_angle_bound;
  int64_t planar_below_bound, planar_below_30;
  int64_t ntri;
} ck_quality_t;

i2m_err_t ck_quality(const ck_mesh_t *m, const ck_topo_t *topo, double ratio_bound,
                     double facet_bound, ck_quality_t *q);

/* ---- fidelity ---- */
typedef struct {
  int64_t value;          /* original label value */
  int64_t voxels;         /* image voxel count */
  double image_volume, mesh_volume, rel_error_pct;
  int64_t tets;
  int64_t image_components, image_components_100, largest_component;
  int64_t mesh_components;
  int64_t large_components, split_components; /* image components of >= the whole threshold;
                                                  those that are not exactly one mesh piece */
  int in_image, in_mesh;
} ck_label_t;

/* An image component and the mesh pieces that stand for it: each piece (face-connected tets of one label) stands for the image component
 * of its label that holds the circumcentres of the largest volume of its tets (a Delaunay
 * image mesh labels a tet by the voxel that holds its circumcentre). */
#define CK_WHOLE_DEFAULT 10000 /* the report's split components: of at least this many voxels */
typedef struct {
  int64_t value, voxels, pieces;
} ck_component_t;

typedef struct {
  double max, p99, mean;   /* mm */
  int64_t count;
  double where[3];         /* world position of the max */
} ck_dist_t;

typedef struct {
  int distances;               /* the distances below were computed */
  double min_spacing, sample_spacing;
  int64_t image_faces, mesh_samples;
  ck_dist_t mesh_to_image, image_to_mesh, two_sided;
  int64_t worst_pair[2];       /* label values on the two sides of the worst image face */
  int64_t worst_component[2];  /* voxel counts of their 6-connected components (0: outside) */
  double worst_thinnest[2];    /* mm: the shortest run of their label through each side's voxel
                                * along an image axis (a spike or sheet finer than delta cannot
                                * be followed, however large its component) */
  int nlabels;
  ck_label_t *labels;          /* owned: [nlabels] union of image labels (no 0) and mesh
                                * labels (0 too, when tets carry it: an extra label) */
  int64_t missing_labels;      /* image labels absent from the mesh */
  int64_t extra_labels;        /* mesh labels absent from the image */
  int64_t image_components_total;
  int64_t ncomponents;
  ck_component_t *components;  /* owned: [ncomponents] every image component (label > 0) */
  double t_mesh_to_image, t_image_to_mesh, t_components; /* seconds */
} ck_fidelity_t;

/** Fidelity figures; the interface distances only when @p distances (they take most of the
 *  time). */
i2m_err_t ck_fidelity(const ck_mesh_t *m, const ck_topo_t *topo, const i2m_image_t *img, int distances,
                      ck_fidelity_t *f);
void ck_fidelity_free(ck_fidelity_t *f);
/** Per label: the image components of >= min_voxels voxels, and those that are not exactly
 *  one mesh piece. */
void ck_fidelity_whole(ck_fidelity_t *f, int64_t min_voxels);
/** Mesh components per label (tets of one label sharing faces): comp[t] (owned) component
 *  id; *ncomp number of components. */
i2m_err_t ck_mesh_components(const ck_mesh_t *m, const ck_topo_t *topo, int64_t **comp,
                             int64_t *ncomp);

/* ---- label colours for the pictures (palette.c) ---- */
#define CK_NAME_MAX 64
#define CK_MIN_DELTA_E 12.0 /* CIE76 distance in CIELAB: two colours side by side are told apart */
enum { CK_COLOUR_NONE = 0, CK_COLOUR_TABLE = 1, CK_COLOUR_REPLACED = 2 };
typedef struct {
  int64_t value;
  int rgb[3];
  int table;               /* CK_COLOUR_TABLE: the colour table's colour; CK_COLOUR_REPLACED: the
                              table's colour was too close to another label's or the background;
                              CK_COLOUR_NONE: no table entry */
  char name[CK_NAME_MAX];  /* from the colour table; "" when none */
} ck_label_colour_t;
typedef struct {
  int64_t n;
  ck_label_colour_t *c;    /* owned: [n] by increasing value */
} ck_palette_t;

/** Colours for the distinct label values[n] (increasing), from the colour table the image
 *  reader found beside the image (@p table: img->names, may be NULL): every two of them, and each and the white
 *  background, distinct (CK_MIN_DELTA_E apart while the gamut allows). */
i2m_err_t ck_palette_build(const i2m_label_names_t *table, const int64_t *values, int64_t n, ck_palette_t *p);
/** The entry of @p value, or NULL. */
const ck_label_colour_t *ck_palette_find(const ck_palette_t *p, int64_t value);
void ck_palette_free(ck_palette_t *p);
/** CIE76 colour difference of two sRGB colours (0..255 each). */
double ck_delta_e(const int a[3], const int b[3]);

/* ---- plots (plot.c) ---- */
#define CK_MAX_SLICES 16
/* A cross-section: the plane normal to world axis x, y or z (the mesh file's coordinates). */
typedef struct {
  const char *text; /* borrowed: as given ("z=40mm"), for messages */
  int axis;         /* 0, 1, 2: x, y, z */
  int in_mm;        /* value is a world coordinate in mm; else a fraction 0..1 of the frame's
                       range along the axis (the image's world box, or the mesh's box) */
  double value;
} ck_slice_t;

/** Parses "AXIS=F" (a fraction 0..1 of the range) or "AXIS=Cmm" (a world coordinate in mm),
 *  AXIS x, y or z.  0 on a bad value, with the reason in why[cap]. */
int ck_slice_parse(const char *text, ck_slice_t *s, char *why, size_t cap);
/** A slice given in mm must lie in the frame's range: an error (I2M_ERR_ARG) names the first
 *  that does not. */
i2m_err_t ck_slice_check(const ck_mesh_t *m, const i2m_image_t *img, const ck_slice_t *s, int n);
/** dir/dihedral_histogram.svg and one cross_section_<axis>.svg per slice (nslices 0: the
 *  three mid-planes x, y, z); a second slice along one axis is cross_section_<axis>_2.svg. */
i2m_err_t ck_plot(const char *dir, const ck_mesh_t *m, const ck_quality_t *q, const i2m_image_t *img,
                  const ck_slice_t *slices, int nslices);

/* ---- geometry (ck_geom.c) ---- */
/** Exact sign of det[b-a; c-a; d-a]. */
int ck_orient3d(const double a[3], const double b[3], const double c[3], const double d[3]);
/** The tet moved to its first vertex and scaled by a power of two to a size near 1: figures
 *  that do not depend on position and scale (angles, radius-edge ratio) computed from these
 *  neither overflow nor lose precision at any coordinates. */
void ck_tet_normalized(const double *p[4], double q[4][3]);
double ck_volume6(const double a[3], const double b[3], const double c[3], const double d[3]);
/** Squared distance from p to triangle abc. */
double ck_dist2_point_triangle(const double p[3], const double a[3], const double b[3],
                               const double c[3]);
/** Smallest planar angle of triangle abc in degrees. */
/** The circumcentre of a tet relative to p0 (0: degenerate, no centre). */
int ck_circumcentre_offset(const double p0[3], const double p1[3], const double p2[3], const double p3[3], double off[3]);
/** Circumcentre of a tet (0: degenerate, no centre). */
int ck_circumcentre(const double p0[3], const double p1[3], const double p2[3], const double p3[3], double cen[3]);
double ck_min_angle_deg(const double a[3], const double b[3], const double c[3]);
/** Value with nearest rank q (0..1) of a[0..n-1]; reorders a. */
double ck_percentile(double *a, int64_t n, double q);

/* ---- a uniform grid of buckets over items with bounding boxes (ck_geom.c) ---- */
typedef struct {
  double lo[3], h[3]; /* set by the caller: lower corner, cell edges */
  int64_t n[3];       /* set by the caller: cells per axis */
  int64_t *start;     /* owned: [cells+1] */
  int64_t *item;      /* owned: items of each cell */
  int64_t nitems;
} ck_grid_t;

typedef void (*ck_bbox_fn)(const void *ctx, int64_t i, double lo[3], double hi[3]);

/** The cell along axis a that holds coordinate x (clamped to the grid). */
static inline int64_t ck_grid_cell(const ck_grid_t *g, int a, double x)
{
  double u = floor((x - g->lo[a]) / g->h[a]);
  if (!(u >= 0)) return 0;
  if (u >= (double)g->n[a]) return g->n[a] - 1;
  return (int64_t)u;
}

/** Files items 0..nitems-1 in every cell their box (from @p bbox) meets; g->lo, h, n set.
 *  Runs on the threads (@p bbox must be safe to call from several): the items of a cell are
 *  in the threads' order, which no search that takes the nearest or the first in another
 *  order depends on.  @p pr (or NULL): a progress line, advanced by 2 * nitems. */
i2m_err_t ck_grid_build(ck_grid_t *g, int64_t nitems, ck_bbox_fn bbox, const void *ctx, ck_progress_t *pr);
void ck_grid_free(ck_grid_t *g);

/* ---- helpers ---- */
static inline int64_t ck_uf_find(int64_t *par, int64_t x)
{
  while (par[x] != x) {
    par[x] = par[par[x]];
    x = par[x];
  }
  return x;
}
static inline void ck_uf_union(int64_t *par, int64_t a, int64_t b)
{
  a = ck_uf_find(par, a);
  b = ck_uf_find(par, b);
  if (a != b) {
    if (a < b)
      par[b] = a;
    else
      par[a] = b;
  }
}


/* ---- everything one run computed, for the reports ---- */
#define CK_MAX_VIOL 32
typedef struct {
  const char *mesh_path, *image_path; /* borrowed */
  const ck_mesh_t *mesh;              /* borrowed */
  const i2m_image_t *img;             /* borrowed, may be NULL */
  ck_validity_t validity;
  int have_quality, have_fidelity;
  ck_quality_t quality;
  ck_fidelity_t fidelity;
  /* thresholds (NAN / -1 when not given) */
  double max_ratio, min_facet_angle, facet_exceptions, max_hausdorff, max_volume_error;
  double max_mesh_to_image, max_p99, min_dihedral, max_dihedral;
  int64_t volume_min_voxels, require_labels, require_whole;
  int nviol;
  char viol[CK_MAX_VIOL][256];
  double t_read, t_validity, t_quality, t_fidelity, t_total;
} ck_result_t;

void ck_report_text(FILE *f, const ck_result_t *r);
void ck_report_json(FILE *f, const ck_result_t *r);

#endif
