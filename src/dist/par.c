/* Dist layer: the parallel context (communicator, rank, size, threads, log prefix), with MPI
 * or, without MPI or without a launcher, a stand-in of one process. */
#include "i2m/dist.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* The number of processes the launcher says it started (0: it does not say). */
static int launched_size(void)
{
  static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "MV2_COMM_WORLD_SIZE"};
  for (size_t k = 0; k < sizeof vars / sizeof *vars; k++) {
    const char *v = getenv(vars[k]);
    if (v && atoi(v) > 0) return atoi(v);
  }
  return 0;
}

static void set_prefix(i2m_par_t *par)
{
  if (par->size > 1) snprintf(par->prefix, sizeof par->prefix, "[rank %d] ", par->rank);
  else par->prefix[0] = '\0';
}

#if I2M_HAVE_MPI

/* Was the process started by an MPI launcher (the variables mpirun, mpiexec, srun set)? */
static bool launched(void)
{
  const char *force = getenv("I2M_MPI");
  if (force && (force[0] == '0' || force[0] == '1')) return force[0] == '1';
  static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMI_RANK", "PMIX_RANK", "MPI_LOCALNRANKS",
                                     "MV2_COMM_WORLD_SIZE"};
  for (size_t k = 0; k < sizeof vars / sizeof *vars; k++)
    if (getenv(vars[k])) return true;
  return false;
}


static MPI_Comm abort_comm = MPI_COMM_NULL; /* (for i2m_abort's hook: a process-wide handle) */

static void abort_hook(void)
{
  if (abort_comm != MPI_COMM_NULL) MPI_Abort(abort_comm, 3);
}

i2m_err_t i2m_par_init(int *argc, char ***argv, i2m_par_t *par)
{
  memset(par, 0, sizeof *par);
  par->comm = MPI_COMM_NULL;
  par->size = par->local_size = 1;
  if (!launched()) return I2M_OK;
  int provided = 0;
  I2M_CHECK(MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided) == MPI_SUCCESS, I2M_ERR_UNSUPPORTED,
            "MPI_Init_thread failed");
  par->mpi = true;
  if (provided < MPI_THREAD_FUNNELED) {
    MPI_Finalize();
    par->mpi = false;
    return I2M_ERROR(I2M_ERR_UNSUPPORTED,
                     "the MPI library gives threads level %d, below MPI_THREAD_FUNNELED (%d): i2m's worker threads need it; "
                     "use an MPI built with thread support",
                     provided, MPI_THREAD_FUNNELED);
  }
  MPI_Comm_dup(MPI_COMM_WORLD, &par->comm);
  MPI_Comm_rank(par->comm, &par->rank);
  MPI_Comm_size(par->comm, &par->size);
  const int want = launched_size();
  if (want > 1 && par->size == 1) { /* N copies, each alone, would each write the whole mesh */
    MPI_Comm_free(&par->comm);
    MPI_Finalize();
    par->mpi = false;
    return I2M_ERROR(I2M_ERR_UNSUPPORTED,
                     "started as %d MPI processes, but each sees only itself: the launcher and i2m's MPI library differ "
                     "(run an Open MPI build with Open MPI's mpirun, an MPICH build (make MPI=mpich) with mpirun.mpich)",
                     want);
  }
  MPI_Comm local;
  MPI_Comm_split_type(par->comm, MPI_COMM_TYPE_SHARED, par->rank, MPI_INFO_NULL, &local);
  MPI_Comm_rank(local, &par->local_rank);
  MPI_Comm_size(local, &par->local_size);
  MPI_Comm_free(&local);
  MPI_Comm_set_errhandler(par->comm, MPI_ERRORS_ARE_FATAL);
  set_prefix(par);
  abort_comm = par->comm;
  i2m_abort_set_hook(abort_hook);
  return I2M_OK;
}

void i2m_par_finalize(i2m_par_t *par)
{
  if (!par->mpi) return;
  abort_comm = MPI_COMM_NULL;
  if (par->comm != MPI_COMM_NULL) MPI_Comm_free(&par->comm);
  MPI_Finalize();
  par->mpi = false;
}

/* Waits for a request, sleeping a little longer each time (a rank that waits long at an
 * agreement, as the others while rank 0 builds the coarse mesh, would otherwise spin in the
 * MPI library and take a core from the ranks that work). */
static void wait_sleeping(MPI_Request *req)
{
  long ns = 20000;
  for (;;) {
    int done = 0;
    MPI_Test(req, &done, MPI_STATUS_IGNORE);
    if (done) return;
    const struct timespec ts = {0, ns};
    nanosleep(&ts, NULL);
    ns = ns < 1000000 ? 2 * ns : 1000000;
  }
}

i2m_err_t i2m_par_agree(const i2m_par_t *par, i2m_err_t err)
{
  if (!par->mpi) return err;
  int mine = err != I2M_OK ? par->rank : par->size, first = par->size;
  MPI_Request req;
  MPI_Iallreduce(&mine, &first, 1, MPI_INT, MPI_MIN, par->comm, &req);
  wait_sleeping(&req);
  if (first == par->size) return I2M_OK;
  char msg[1024];
  int code = (int)err;
  if (par->rank == first) snprintf(msg, sizeof msg, "%s", i2m_error_message());
  MPI_Bcast(&code, 1, MPI_INT, first, par->comm);
  MPI_Bcast(msg, (int)sizeof msg, MPI_CHAR, first, par->comm);
  msg[sizeof msg - 1] = '\0';
  if (par->size > 1 && strncmp(msg, "[rank ", 6) != 0) /* (an error agreed on already keeps its prefix) */
    return i2m_error_set((i2m_err_t)code, __FILE__, __LINE__, "[rank %d] %s", first, msg);
  return i2m_error_set((i2m_err_t)code, __FILE__, __LINE__, "%s", msg);
}

void i2m_par_abort(const i2m_par_t *par, int code)
{
  fflush(stdout);
  fflush(stderr);
  if (par->mpi) MPI_Abort(par->comm, code);
  exit(code);
}

double i2m_par_max(const i2m_par_t *par, double x)
{
  double y = x;
  if (par->mpi) MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, MPI_MAX, par->comm);
  return y;
}

double i2m_par_sum(const i2m_par_t *par, double x)
{
  double y = x;
  if (par->mpi) MPI_Allreduce(&x, &y, 1, MPI_DOUBLE, MPI_SUM, par->comm);
  return y;
}

void i2m_par_sum_i64(const i2m_par_t *par, int64_t *x, int n)
{
  if (par->mpi) MPI_Allreduce(MPI_IN_PLACE, x, n, MPI_INT64_T, MPI_SUM, par->comm);
}

int i2m_par_bcast_int(const i2m_par_t *par, int x)
{
  if (par->mpi) MPI_Bcast(&x, 1, MPI_INT, 0, par->comm);
  return x;
}

void i2m_par_barrier(const i2m_par_t *par)
{
  if (par->mpi) MPI_Barrier(par->comm);
}

#else /* no MPI: one process */

i2m_err_t i2m_par_init(int *argc, char ***argv, i2m_par_t *par)
{
  (void)argc;
  (void)argv;
  memset(par, 0, sizeof *par);
  par->size = par->local_size = 1;
  par->comm = 0;
  I2M_CHECK(launched_size() <= 1, I2M_ERR_UNSUPPORTED,
            "started as %d MPI processes, but this i2m was built without MPI: each would mesh the whole image (make with "
            "mpicc)", launched_size());
  set_prefix(par);
  return I2M_OK;
}

void i2m_par_finalize(i2m_par_t *par) { (void)par; }
i2m_err_t i2m_par_agree(const i2m_par_t *par, i2m_err_t err)
{
  (void)par;
  return err;
}
void i2m_par_abort(const i2m_par_t *par, int code)
{
  (void)par;
  fflush(stdout);
  fflush(stderr);
  exit(code);
}
double i2m_par_max(const i2m_par_t *par, double x)
{
  (void)par;
  return x;
}
double i2m_par_sum(const i2m_par_t *par, double x)
{
  (void)par;
  return x;
}
void i2m_par_sum_i64(const i2m_par_t *par, int64_t *x, int n)
{
  (void)par;
  (void)x;
  (void)n;
}
int i2m_par_bcast_int(const i2m_par_t *par, int x)
{
  (void)par;
  return x;
}
void i2m_par_barrier(const i2m_par_t *par) { (void)par; }

#endif

int i2m_par_node_threads(const i2m_par_t *par, int T)
{
  const int avail = i2m_threads_available();
  const int n = T * par->local_size < avail ? T * par->local_size : avail;
  return n > T ? n : T;
}

void i2m_par_self(i2m_par_t *par)
{
  memset(par, 0, sizeof *par);
  par->size = par->local_size = 1;
#if I2M_HAVE_MPI
  par->comm = MPI_COMM_NULL;
#endif
}

/* ---- the distance transform, each rank computing a share ---- */

#if I2M_HAVE_MPI
/* i2m_edt_share_t's exchange over the ranks of ctx (a parallel context). */
static i2m_err_t edt_exchange(void *ctx, i2m_err_t err, int32_t *buf, const int64_t *count, const int64_t *displ,
                              int64_t nblocks, int64_t stride)
{
  const i2m_par_t *par = ctx;
  I2M_CALL(i2m_par_agree(par, err));
  int *c = NULL;
  I2M_CALL(i2m_par_agree(par, i2m_malloc(2 * (size_t)par->size, sizeof *c, &c)));
  for (int q = 0; q < par->size; q++) { /* (each below 2^31: the box is) */
    c[q] = (int)count[q];
    c[par->size + q] = (int)displ[q];
  }
  for (int64_t b = 0; b < nblocks; b++)
    MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, buf + b * stride, c, c + par->size, MPI_INT32_T, par->comm);
  i2m_free(&c);
  return I2M_OK;
}
#endif

i2m_err_t i2m_dist_edt_create(const i2m_par_t *par, const i2m_image_t *img, i2m_edt_t **out)
{
#if I2M_HAVE_MPI
  if (par->mpi && par->size > 1) {
    const i2m_edt_share_t share = {par->rank, par->size, edt_exchange, (void *)par};
    return i2m_par_agree(par, i2m_edt_create_shared(img, &share, out)); /* (every rank calls each exchange) */
  }
#endif
  return i2m_par_agree(par, i2m_edt_create(img, out));
}

/* ---- the image, read once ---- */

#if I2M_HAVE_MPI
/* n bytes from rank 0 to every rank, in pieces an int counts. */
static void bcast_bytes(const i2m_par_t *par, void *p, uint64_t n)
{
  const uint64_t piece = (uint64_t)1 << 30;
  for (uint64_t at = 0; at < n; at += piece)
    MPI_Bcast((char *)p + at, (int)(n - at < piece ? n - at : piece), MPI_BYTE, 0, par->comm);
}

static i2m_err_t image_bcast(const i2m_par_t *par, i2m_err_t err, i2m_image_t **out)
{
  void *buf = NULL;
  size_t len = 0;
  if (err == I2M_OK && par->rank == 0) err = i2m_image_pack_meta(*out, &buf, &len);
  I2M_CALL(i2m_par_agree(par, err));
  uint64_t n = len;
  MPI_Bcast(&n, 1, MPI_UINT64_T, 0, par->comm);
  if (par->rank != 0) err = i2m_malloc((size_t)n, 1, &buf);
  if ((err = i2m_par_agree(par, err)) == I2M_OK) bcast_bytes(par, buf, n);
  if (err == I2M_OK && par->rank != 0) err = i2m_image_unpack_meta(buf, (size_t)n, out);
  i2m_free(&buf);
  I2M_CALL(i2m_par_agree(par, err));
  const i2m_image_t *img = *out;
  const uint64_t nvox = (uint64_t)img->n[0] * (uint64_t)img->n[1] * (uint64_t)img->n[2];
  bcast_bytes(par, img->vox, nvox);
  if (img->vox_hi) bcast_bytes(par, img->vox_hi, nvox);
  return I2M_OK;
}
#endif

i2m_err_t i2m_dist_image_read(const i2m_par_t *par, const char *path, const i2m_image_read_opts_t *opts,
                              i2m_image_t **out)
{
  *out = NULL;
#if I2M_HAVE_MPI
  if (par->mpi && par->size > 1) {
    const i2m_err_t err = image_bcast(par, par->rank == 0 ? i2m_image_read_with(path, opts, out, NULL) : I2M_OK, out);
    if (err != I2M_OK) i2m_image_destroy(out);
    return err;
  }
#endif
  return i2m_par_agree(par, i2m_image_read_with(path, opts, out, NULL));
}
