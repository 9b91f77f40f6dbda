/* Test tool (no layer of i2m): a deliberately bad MPI program for the PMPI funneled check
 * (pmpi_funneled.c).  It initialises MPI with MPI_THREAD_FUNNELED and starts a second
 * thread; with the argument "bad" that thread calls MPI_Comm_rank (against FUNNELED: the
 * wrapper must stop it), with "good" the main thread makes the same calls after joining it
 * (the wrapper must let it finish with exit 0).  Open MPI itself does not notice the bad
 * call, so without the wrapper both variants end with 0. */
#include <mpi.h>
#include <pthread.h>
#include <stdio.h>
#include <string.h>

static void *second_thread(void *arg)
{
  int *rank = arg;
  MPI_Comm_rank(MPI_COMM_WORLD, rank); /* the call FUNNELED forbids */
  return NULL;
}

int main(int argc, char **argv)
{
  const int bad = argc > 1 && strcmp(argv[1], "bad") == 0;
  int provided = 0, rank = -1, size = 0;
  MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
  MPI_Comm_size(MPI_COMM_WORLD, &size);
  if (bad) {
    pthread_t th;
    if (pthread_create(&th, NULL, second_thread, &rank) != 0) return 2;
    pthread_join(th, NULL);
  } else {
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
  }
  MPI_Barrier(MPI_COMM_WORLD);
  int sum = 0;
  MPI_Allreduce(&rank, &sum, 1, MPI_INT, MPI_SUM, MPI_COMM_WORLD);
  if (rank == 0) printf("funneled_bad: %d ranks, sum of ranks %d (%s)\n", size, sum, bad ? "bad" : "good");
  MPI_Finalize();
  return 0;
}
