/* The coloured solve's second thread: crew.h. */
#include <stdlib.h>

#include "crew.h"

#if defined(_WIN32) || defined(__STDC_NO_ATOMICS__)

/* No crew is ever made, so none is ever run. */
struct hd_crew *hd_crew_new(void) { return NULL; }
void hd_crew_free(struct hd_crew *c) { (void)c; }

void hd_crew_run(struct hd_crew *c, hd_task task, void *job)
{
    (void)c;
    (void)task;
    (void)job;
}

void hd_crew_meet(struct hd_crew *c, int lane)
{
    (void)c;
    (void)lane;
}

#else

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <unistd.h>

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define hd_relax() _mm_pause()
#else
#define hd_relax() ((void)0)
#endif

/* Spins at a barrier before each yield of the core, and spins of an idle worker before it
 * sleeps (each a pause of some tens of nanoseconds). */
#define HD_MEET_SPINS 200
#define HD_IDLE_SPINS 2000

/* The two lanes' counts of barriers each on its own cache line, so that one lane's count
 * does not slow the other's spinning. */
struct hd_crew {
    _Alignas(64) atomic_long arrived;  /* both lanes' arrivals at barriers, ever */
    _Alignas(64) long met[2];          /* per lane: its barriers */
    _Alignas(64) atomic_long go;       /* tasks handed to the worker, ever */
    hd_task task;                      /* NULL: stop */
    void *job;
    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t worker;
};

void hd_crew_meet(struct hd_crew *c, int lane)
{
    const long target = 2 * ++c->met[lane];
    atomic_fetch_add_explicit(&c->arrived, 1, memory_order_acq_rel);
    for (long spin = 1; atomic_load_explicit(&c->arrived, memory_order_acquire) < target;
         ++spin) {
        if (spin % HD_MEET_SPINS == 0)
            sched_yield();
        else
            hd_relax();
    }
}

static void *hd_work(void *crew)
{
    struct hd_crew *c = crew;
    long seen = 0;
    for (;;) {
        long go = atomic_load_explicit(&c->go, memory_order_acquire);
        for (long spin = 0; go == seen && spin < HD_IDLE_SPINS; ++spin) {
            hd_relax();
            go = atomic_load_explicit(&c->go, memory_order_acquire);
        }
        if (go == seen) {
            pthread_mutex_lock(&c->lock);
            while ((go = atomic_load_explicit(&c->go, memory_order_acquire)) == seen)
                pthread_cond_wait(&c->wake, &c->lock);
            pthread_mutex_unlock(&c->lock);
        }
        seen = go;
        if (c->task == NULL)
            return NULL;
        c->task(c->job, 1);
        hd_crew_meet(c, 1);
    }
}

struct hd_crew *hd_crew_new(void)
{
    if (sysconf(_SC_NPROCESSORS_ONLN) < 2)
        return NULL;  /* a second thread would only take turns with the first */
    struct hd_crew *c = aligned_alloc(64, sizeof(struct hd_crew));
    if (c == NULL)
        return NULL;
    atomic_init(&c->arrived, 0);
    atomic_init(&c->go, 0);
    c->met[0] = c->met[1] = 0;
    c->task = NULL;
    c->job = NULL;
    if (pthread_mutex_init(&c->lock, NULL) != 0) {
        free(c);
        return NULL;
    }
    if (pthread_cond_init(&c->wake, NULL) != 0) {
        pthread_mutex_destroy(&c->lock);
        free(c);
        return NULL;
    }
    if (pthread_create(&c->worker, NULL, hd_work, c) != 0) {
        pthread_cond_destroy(&c->wake);
        pthread_mutex_destroy(&c->lock);
        free(c);
        return NULL;
    }
    return c;
}

/* Hand the worker `task` (NULL: stop) and wake it if it sleeps. */
static void hd_hand(struct hd_crew *c, hd_task task, void *job)
{
    pthread_mutex_lock(&c->lock);
    c->task = task;
    c->job = job;
    atomic_fetch_add_explicit(&c->go, 1, memory_order_release);
    pthread_cond_signal(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

void hd_crew_free(struct hd_crew *c)
{
    if (c == NULL)
        return;
    hd_hand(c, NULL, NULL);
    pthread_join(c->worker, NULL);
    pthread_cond_destroy(&c->wake);
    pthread_mutex_destroy(&c->lock);
    free(c);
}

void hd_crew_run(struct hd_crew *c, hd_task task, void *job)
{
    hd_hand(c, task, job);
    task(job, 0);
    hd_crew_meet(c, 0);
}

#endif
