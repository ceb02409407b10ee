/* A second thread for the coloured solve (wide.c): one worker, started once and kept,
 * that runs its half of a task beside the calling thread, and a barrier between the two.
 *
 * The barrier spins (the colours of a pass are microseconds apart), yielding the core
 * after a while so that a worker that lost its core to another process gets it back; an
 * idle worker spins a little after its task, then sleeps until the next one. Where there
 * are no POSIX threads (MSVC), hd_crew_new gives NULL and the solve keeps one thread.
 */
#ifndef HECKER_DYNAMICS_CREW_H
#define HECKER_DYNAMICS_CREW_H

struct hd_crew;

/* A task's half for `lane` (0: the calling thread, 1: the worker) of `job`. */
typedef void (*hd_task)(void *job, int lane);

/* The worker, started; NULL where it cannot be (no threads, or none to be had). */
struct hd_crew *hd_crew_new(void);
/* Stop the worker and free it (NULL: nothing). */
void hd_crew_free(struct hd_crew *c);
/* task(job, 0) on this thread and task(job, 1) on the worker; returns when both ended. */
void hd_crew_run(struct hd_crew *c, hd_task task, void *job);
/* Wait until the other lane arrived here too: each lane must meet as often as the other
 * within a task. */
void hd_crew_meet(struct hd_crew *c, int lane);

#endif
