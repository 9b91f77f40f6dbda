/* i2m io layer (layer 7): the run report, printed as a summary and written as JSON. */
#ifndef I2M_REPORT_H
#define I2M_REPORT_H

#include <stdio.h>

#include "i2m/dist.h"
#include "i2m/quality.h"
#include "i2m/refine.h"
#include "i2m/threads.h"

#ifdef __cplusplus
extern "C" {
#endif

/** Phases timed by the driver, in the order they run. */
enum {
  I2M_PHASE_READ,
  I2M_PHASE_EDT,
  I2M_PHASE_REFINE,
  I2M_PHASE_SLIVERS, /**< the optional sliver perturbation (0 s when off) */
  I2M_PHASE_EXTRACT,
  I2M_PHASE_WRITE,
  I2M_PHASE_QUALITY,
  I2M_NPHASES
};

/** Everything a run reports (all borrowed). */
typedef struct {
  const char *input, *output;
  const i2m_image_t *img;
  const i2m_refine_params_t *params; /**< delta resolved */
  i2m_refine_stats_t stats;
  int64_t nv, nt, ntri;              /**< output mesh */
  int64_t working_tets;              /**< tets of the triangulation at the end (all labels) */
  uint64_t checksum;                 /**< order-independent checksum of that triangulation
                                          (i2m_dt_checksum): equal for equal meshes */
  double phase_seconds[I2M_NPHASES];
  double total_seconds;
  size_t peak_rss;                   /**< bytes */
  int threads, ranks;
  const i2m_threads_report_t *team;  /**< per-thread figures, or NULL */
  const i2m_dist_report_t *dist;     /**< the distributed level's figures (per rank), or NULL */
  const i2m_quality_t *quality;
 const i2m_label_pieces_t *pieces; /**< per label index: components and pieces, or NULL */
  int64_t whole_min_voxels;         /**< the census's large components: at least this many voxels */
  double sliver_angle;               /**< the perturbation's bound (0: it did not run) */
  i2m_sliver_stats_t slivers;        /**< what it did */
  i2m_dihedral_bands_t bands_before; /**< the dihedral bands before it (when it ran) */
} i2m_report_t;

/** The mesh volume of a label may differ from its voxel volume by this fraction before a
 *  warning says so. */
#define I2M_VOLUME_WARN_FRACTION 0.05

/** One warning line on @p f for every label of the image that the mesh leaves out, or whose
 *  mesh volume differs from its voxel volume by more than @p tolerance (a fraction, e.g.
 *  I2M_VOLUME_WARN_FRACTION), naming the label's value, its tissue name when @p names (may be
 *  NULL) has one, and its voxel count.  @p q: the whole mesh's figures.  Returns the number
 *  of lines.  Not collective: call it on one rank. */
int i2m_report_warn_labels(FILE *f, const i2m_quality_t *q, const i2m_image_t *img, const i2m_label_names_t *names,
                           double tolerance);

/** Name of a phase ("read", "distance_transform", ...). */
const char *i2m_phase_name(int phase);
/** A human-readable summary. */
void i2m_report_print(FILE *f, const i2m_report_t *r);
/** The JSON report; the message names the file on error. */
i2m_err_t i2m_report_write_json(const char *path, const i2m_report_t *r);

#ifdef __cplusplus
}
#endif
#endif
