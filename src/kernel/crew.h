/* A second thread for the coloured solve (wide.c): one worker, started once and kept, that
 * takes chunks of a colour's work beside the calling thread.
 *
 * The calling thread hands out a colour as `count` chunks and takes them itself too; each
 * chunk goes to whichever thread asks first (an atomic counter), and the colour ends when
 * every chunk is done. So the calling thread waits only for a chunk the worker is in the
 * middle of, never for a worker that lost its core to another process: on a busy machine it
 * simply solves more chunks itself. An idle worker spins a little, then sleeps until the
 * next task. Where there are no POSIX threads (MSVC), hd_crew_new gives NULL and the solve
 * keeps one thread.
 */
#ifndef HECKER_DYNAMICS_CREW_H
#define HECKER_DYNAMICS_CREW_H

struct hd_crew;

/* The most chunks of a colour. */
#define HD_MOST_CHUNKS 65535

/* Chunk `chunk` of `job`'s current colour; returns its largest change (>= 0, no NaN). */
typedef double (*hd_chunk)(void *job, long chunk);

/* The worker, started; NULL where it cannot be (no threads, one processor, no memory). */
struct hd_crew *hd_crew_new(void);
/* Stop the worker and free it (NULL: nothing). */
void hd_crew_free(struct hd_crew *c);
/* Wake the worker for a task of several colours. */
void hd_crew_begin(struct hd_crew *c);
/* Chunks 0 to count - 1 (count <= HD_MOST_CHUNKS) of `job` by both threads, and
 * alone(job) by this one meanwhile; returns once every chunk is done, the largest of
 * their changes and alone's. */
double hd_crew_share(struct hd_crew *c, hd_chunk chunk, void *job, long count,
                     double (*alone)(void *job));

#endif
