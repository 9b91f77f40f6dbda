/* Test tool (no layer of i2m): a PMPI wrapper that checks MPI_THREAD_FUNNELED.
 *
 * Built as a shared library and preloaded into every rank (mpirun -x LD_PRELOAD=...): its
 * MPI_* functions come before libmpi's, check that the calling thread is the one that called
 * MPI_Init_thread (or MPI_Init), count the call and hand it to the PMPI_* twin.  A call from
 * any other thread prints one line naming the MPI function and the rank, then aborts the job
 * (PMPI_Abort, exit code 86).  With PMPI_FUNNELED_REPORT=1 in the environment, MPI_Finalize
 * prints one line per rank on stderr:
 *     pmpi_funneled: rank R: N MPI calls, all on the thread of MPI_Init_thread
 * so that a test can tell that the wrapper was loaded and saw calls.  It wraps every MPI
 * function i2m calls (grep -o 'MPI_[A-Z][a-z_]*(' src/) and a few close relatives. */
#include <mpi.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>

#define FUNNELED_ABORT_CODE 86

static pthread_t main_thread;        /* the thread that initialised MPI */
static atomic_int initialised;       /* main_thread is set */
static atomic_long calls;            /* MPI calls seen, from the right thread */

/* The thread check before every call: on another thread, one line and the end of the job. */
static void funneled(const char *fn)
{
  if (!atomic_load(&initialised)) return; /* (before MPI_Init_thread: nothing to compare with) */
  if (pthread_equal(pthread_self(), main_thread)) {
    atomic_fetch_add(&calls, 1);
    return;
  }
  int rank = -1;
  PMPI_Comm_rank(MPI_COMM_WORLD, &rank);
  fprintf(stderr, "pmpi_funneled: rank %d: %s called from a thread other than the one that called MPI_Init_thread\n",
          rank, fn);
  fflush(stderr);
  PMPI_Abort(MPI_COMM_WORLD, FUNNELED_ABORT_CODE);
}

static void remember_thread(void)
{
  main_thread = pthread_self();
  atomic_store(&initialised, 1);
}

int MPI_Init_thread(int *argc, char ***argv, int required, int *provided)
{
  const int err = PMPI_Init_thread(argc, argv, required, provided);
  if (err == MPI_SUCCESS) remember_thread();
  return err;
}

int MPI_Init(int *argc, char ***argv)
{
  const int err = PMPI_Init(argc, argv);
  if (err == MPI_SUCCESS) remember_thread();
  return err;
}

int MPI_Finalize(void)
{
  funneled("MPI_Finalize");
  const char *report = getenv("PMPI_FUNNELED_REPORT");
  if (report && report[0] == '1') {
    int rank = -1;
    PMPI_Comm_rank(MPI_COMM_WORLD, &rank);
    fprintf(stderr, "pmpi_funneled: rank %d: %ld MPI calls, all on the thread of MPI_Init_thread\n", rank,
            atomic_load(&calls));
    fflush(stderr);
  }
  return PMPI_Finalize();
}

int MPI_Abort(MPI_Comm comm, int errorcode)
{
  funneled("MPI_Abort");
  return PMPI_Abort(comm, errorcode);
}

/* ---- communicators ---- */

int MPI_Comm_dup(MPI_Comm comm, MPI_Comm *newcomm)
{
  funneled("MPI_Comm_dup");
  return PMPI_Comm_dup(comm, newcomm);
}

int MPI_Comm_free(MPI_Comm *comm)
{
  funneled("MPI_Comm_free");
  return PMPI_Comm_free(comm);
}

int MPI_Comm_rank(MPI_Comm comm, int *rank)
{
  funneled("MPI_Comm_rank");
  return PMPI_Comm_rank(comm, rank);
}

int MPI_Comm_size(MPI_Comm comm, int *size)
{
  funneled("MPI_Comm_size");
  return PMPI_Comm_size(comm, size);
}

int MPI_Comm_split(MPI_Comm comm, int color, int key, MPI_Comm *newcomm)
{
  funneled("MPI_Comm_split");
  return PMPI_Comm_split(comm, color, key, newcomm);
}

int MPI_Comm_split_type(MPI_Comm comm, int split_type, int key, MPI_Info info, MPI_Comm *newcomm)
{
  funneled("MPI_Comm_split_type");
  return PMPI_Comm_split_type(comm, split_type, key, info, newcomm);
}

int MPI_Comm_set_errhandler(MPI_Comm comm, MPI_Errhandler errhandler)
{
  funneled("MPI_Comm_set_errhandler");
  return PMPI_Comm_set_errhandler(comm, errhandler);
}

/* ---- point to point ---- */

int MPI_Send(const void *buf, int count, MPI_Datatype datatype, int dest, int tag, MPI_Comm comm)
{
  funneled("MPI_Send");
  return PMPI_Send(buf, count, datatype, dest, tag, comm);
}

int MPI_Ssend(const void *buf, int count, MPI_Datatype datatype, int dest, int tag, MPI_Comm comm)
{
  funneled("MPI_Ssend");
  return PMPI_Ssend(buf, count, datatype, dest, tag, comm);
}

int MPI_Isend(const void *buf, int count, MPI_Datatype datatype, int dest, int tag, MPI_Comm comm, MPI_Request *request)
{
  funneled("MPI_Isend");
  return PMPI_Isend(buf, count, datatype, dest, tag, comm, request);
}

int MPI_Recv(void *buf, int count, MPI_Datatype datatype, int source, int tag, MPI_Comm comm, MPI_Status *status)
{
  funneled("MPI_Recv");
  return PMPI_Recv(buf, count, datatype, source, tag, comm, status);
}

int MPI_Irecv(void *buf, int count, MPI_Datatype datatype, int source, int tag, MPI_Comm comm, MPI_Request *request)
{
  funneled("MPI_Irecv");
  return PMPI_Irecv(buf, count, datatype, source, tag, comm, request);
}

int MPI_Sendrecv(const void *sendbuf, int sendcount, MPI_Datatype sendtype, int dest, int sendtag, void *recvbuf,
                 int recvcount, MPI_Datatype recvtype, int source, int recvtag, MPI_Comm comm, MPI_Status *status)
{
  funneled("MPI_Sendrecv");
  return PMPI_Sendrecv(sendbuf, sendcount, sendtype, dest, sendtag, recvbuf, recvcount, recvtype, source, recvtag, comm,
                       status);
}

int MPI_Iprobe(int source, int tag, MPI_Comm comm, int *flag, MPI_Status *status)
{
  funneled("MPI_Iprobe");
  return PMPI_Iprobe(source, tag, comm, flag, status);
}

int MPI_Probe(int source, int tag, MPI_Comm comm, MPI_Status *status)
{
  funneled("MPI_Probe");
  return PMPI_Probe(source, tag, comm, status);
}

int MPI_Test(MPI_Request *request, int *flag, MPI_Status *status)
{
  funneled("MPI_Test");
  return PMPI_Test(request, flag, status);
}

int MPI_Testall(int count, MPI_Request array_of_requests[], int *flag, MPI_Status array_of_statuses[])
{
  funneled("MPI_Testall");
  return PMPI_Testall(count, array_of_requests, flag, array_of_statuses);
}

int MPI_Wait(MPI_Request *request, MPI_Status *status)
{
  funneled("MPI_Wait");
  return PMPI_Wait(request, status);
}

int MPI_Waitall(int count, MPI_Request array_of_requests[], MPI_Status *array_of_statuses)
{
  funneled("MPI_Waitall");
  return PMPI_Waitall(count, array_of_requests, array_of_statuses);
}

int MPI_Get_count(const MPI_Status *status, MPI_Datatype datatype, int *count)
{
  funneled("MPI_Get_count");
  return PMPI_Get_count(status, datatype, count);
}

/* ---- collectives ---- */

int MPI_Barrier(MPI_Comm comm)
{
  funneled("MPI_Barrier");
  return PMPI_Barrier(comm);
}

int MPI_Bcast(void *buffer, int count, MPI_Datatype datatype, int root, MPI_Comm comm)
{
  funneled("MPI_Bcast");
  return PMPI_Bcast(buffer, count, datatype, root, comm);
}

int MPI_Allreduce(const void *sendbuf, void *recvbuf, int count, MPI_Datatype datatype, MPI_Op op, MPI_Comm comm)
{
  funneled("MPI_Allreduce");
  return PMPI_Allreduce(sendbuf, recvbuf, count, datatype, op, comm);
}

int MPI_Iallreduce(const void *sendbuf, void *recvbuf, int count, MPI_Datatype datatype, MPI_Op op, MPI_Comm comm,
                   MPI_Request *request)
{
  funneled("MPI_Iallreduce");
  return PMPI_Iallreduce(sendbuf, recvbuf, count, datatype, op, comm, request);
}

int MPI_Reduce(const void *sendbuf, void *recvbuf, int count, MPI_Datatype datatype, MPI_Op op, int root, MPI_Comm comm)
{
  funneled("MPI_Reduce");
  return PMPI_Reduce(sendbuf, recvbuf, count, datatype, op, root, comm);
}

int MPI_Exscan(const void *sendbuf, void *recvbuf, int count, MPI_Datatype datatype, MPI_Op op, MPI_Comm comm)
{
  funneled("MPI_Exscan");
  return PMPI_Exscan(sendbuf, recvbuf, count, datatype, op, comm);
}

int MPI_Scan(const void *sendbuf, void *recvbuf, int count, MPI_Datatype datatype, MPI_Op op, MPI_Comm comm)
{
  funneled("MPI_Scan");
  return PMPI_Scan(sendbuf, recvbuf, count, datatype, op, comm);
}

int MPI_Alltoall(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, int recvcount,
                 MPI_Datatype recvtype, MPI_Comm comm)
{
  funneled("MPI_Alltoall");
  return PMPI_Alltoall(sendbuf, sendcount, sendtype, recvbuf, recvcount, recvtype, comm);
}

int MPI_Alltoallv(const void *sendbuf, const int sendcounts[], const int sdispls[], MPI_Datatype sendtype, void *recvbuf,
                  const int recvcounts[], const int rdispls[], MPI_Datatype recvtype, MPI_Comm comm)
{
  funneled("MPI_Alltoallv");
  return PMPI_Alltoallv(sendbuf, sendcounts, sdispls, sendtype, recvbuf, recvcounts, rdispls, recvtype, comm);
}

int MPI_Gather(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, int recvcount,
               MPI_Datatype recvtype, int root, MPI_Comm comm)
{
  funneled("MPI_Gather");
  return PMPI_Gather(sendbuf, sendcount, sendtype, recvbuf, recvcount, recvtype, root, comm);
}

int MPI_Gatherv(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, const int recvcounts[],
                const int displs[], MPI_Datatype recvtype, int root, MPI_Comm comm)
{
  funneled("MPI_Gatherv");
  return PMPI_Gatherv(sendbuf, sendcount, sendtype, recvbuf, recvcounts, displs, recvtype, root, comm);
}

int MPI_Allgather(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, int recvcount,
                  MPI_Datatype recvtype, MPI_Comm comm)
{
  funneled("MPI_Allgather");
  return PMPI_Allgather(sendbuf, sendcount, sendtype, recvbuf, recvcount, recvtype, comm);
}

int MPI_Allgatherv(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, const int recvcounts[],
                   const int displs[], MPI_Datatype recvtype, MPI_Comm comm)
{
  funneled("MPI_Allgatherv");
  return PMPI_Allgatherv(sendbuf, sendcount, sendtype, recvbuf, recvcounts, displs, recvtype, comm);
}

int MPI_Scatter(const void *sendbuf, int sendcount, MPI_Datatype sendtype, void *recvbuf, int recvcount,
                MPI_Datatype recvtype, int root, MPI_Comm comm)
{
  funneled("MPI_Scatter");
  return PMPI_Scatter(sendbuf, sendcount, sendtype, recvbuf, recvcount, recvtype, root, comm);
}

int MPI_Scatterv(const void *sendbuf, const int sendcounts[], const int displs[], MPI_Datatype sendtype, void *recvbuf,
                 int recvcount, MPI_Datatype recvtype, int root, MPI_Comm comm)
{
  funneled("MPI_Scatterv");
  return PMPI_Scatterv(sendbuf, sendcounts, displs, sendtype, recvbuf, recvcount, recvtype, root, comm);
}
