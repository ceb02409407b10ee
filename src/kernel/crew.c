/* The coloured solve's second thread: crew.h. */
#include <stdlib.h>

#include "crew.h"

#if defined(_WIN32) || defined(__STDC_NO_ATOMICS__)

/* No crew is ever made, so none is ever asked for work. */
struct hd_crew *hd_crew_new(void) { return NULL; }
void hd_crew_free(struct hd_crew *c) { (void)c; }
void hd_crew_begin(struct hd_crew *c) { (void)c; }

double hd_crew_share(struct hd_crew *c, hd_chunk chunk, void *job, long count,
                     double (*alone)(void *job))
{
    (void)c;
    (void)chunk;
    (void)job;
    (void)count;
    (void)alone;
    return 0.0;
}

#else

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <time.h>
#include <unistd.h>

#include "floats.h"

#if defined(__x86_64__) || defined(__i386__)
#include <immintrin.h>
#define hd_relax() _mm_pause()
#else
#define hd_relax() ((void)0)
#endif

/* How long an idle worker polls for work before it sleeps (ns), reading the clock every
 * HD_POLLS polls: long enough to bridge the gaps between the colours and passes of a
 * step, short enough not to hold a core that other processes want between steps (the
 * crew's barrier-free sharing lets this thread solve alone meanwhile). */
#define HD_IDLE_NS 200000
#define HD_POLLS 64
/* The work word, read and changed at once: the colour handed out (its sequence number,
 * 32 bits), its chunks (16 bits) and the next chunk (16 bits). */
#define HD_CHUNK_BITS 16
#define HD_CHUNK_MASK ((UINT64_C(1) << HD_CHUNK_BITS) - 1)

/* What both threads poll, apart from what each writes. */
struct hd_crew {
    _Alignas(64) _Atomic uint64_t work;  /* colour, chunks, next chunk */
    hd_chunk chunk;                      /* the colour's, set before it is handed out */
    void *job;
    _Alignas(64) atomic_long done;      /* chunks of the colour done */
    double found;                        /* the worker's largest change of the colour */
    _Alignas(64) long go;                /* tasks begun, under `lock` */
    int quit;
    pthread_mutex_t lock;
    pthread_cond_t wake;
    pthread_t worker;
};

/* Take the next chunk of the colour `word` names, if any is left and the colour is still
 * the one handed out: its number, or -1. */
static long hd_take(struct hd_crew *c, uint64_t word)
{
    for (;;) {
        if ((word & HD_CHUNK_MASK) >= ((word >> HD_CHUNK_BITS) & HD_CHUNK_MASK))
            return -1;
        if (atomic_compare_exchange_weak_explicit(&c->work, &word, word + 1,
                                                  memory_order_acq_rel, memory_order_acquire))
            return (long)(word & HD_CHUNK_MASK);
        /* `word` now holds what is there: the same colour with fewer chunks, or a new one */
    }
}

/* A monotonic clock (ns). */
static long hd_now(void)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (long)now.tv_sec * 1000000000L + now.tv_nsec;
}

static void *hd_work(void *crew)
{
    struct hd_crew *c = crew;
    long seen = 0;
    for (;;) {
        pthread_mutex_lock(&c->lock);
        while (c->go == seen && !c->quit)
            pthread_cond_wait(&c->wake, &c->lock);
        seen = c->go;
        const int quit = c->quit;
        pthread_mutex_unlock(&c->lock);
        if (quit)
            return NULL;
        for (long polls = 1, last = hd_now();; ++polls) {
            const long taken = hd_take(c, atomic_load_explicit(&c->work, memory_order_acquire));
            if (taken >= 0) {
                /* The colour cannot end before this chunk is done, so its job stays. */
                c->found = hd_max(c->found, c->chunk(c->job, taken));
                atomic_fetch_add_explicit(&c->done, 1, memory_order_release);
                last = hd_now();
            } else if (polls % HD_POLLS == 0 && hd_now() - last > HD_IDLE_NS) {
                break;
            } else {
                hd_relax();
            }
        }
    }
}

struct hd_crew *hd_crew_new(void)
{
    if (sysconf(_SC_NPROCESSORS_ONLN) < 2)
        return NULL;  /* a second thread would only take turns with the first */
    struct hd_crew *c = aligned_alloc(64, sizeof(struct hd_crew));
    if (c == NULL)
        return NULL;
    atomic_init(&c->work, 0);
    atomic_init(&c->done, 0);
    c->chunk = NULL;
    c->job = NULL;
    c->found = 0.0;
    c->go = 0;
    c->quit = 0;
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

void hd_crew_free(struct hd_crew *c)
{
    if (c == NULL)
        return;
    pthread_mutex_lock(&c->lock);
    c->quit = 1;
    pthread_cond_signal(&c->wake);
    pthread_mutex_unlock(&c->lock);
    pthread_join(c->worker, NULL);
    pthread_cond_destroy(&c->wake);
    pthread_mutex_destroy(&c->lock);
    free(c);
}

void hd_crew_begin(struct hd_crew *c)
{
    pthread_mutex_lock(&c->lock);
    c->go += 1;
    pthread_cond_signal(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

double hd_crew_share(struct hd_crew *c, hd_chunk chunk, void *job, long count,
                     double (*alone)(void *job))
{
    /* The last colour's chunks are all done, so the worker touches none of this until the
     * new colour is handed out by the release below. */
    c->chunk = chunk;
    c->job = job;
    c->found = 0.0;
    atomic_store_explicit(&c->done, 0, memory_order_relaxed);
    const uint64_t colour = ((atomic_load_explicit(&c->work, memory_order_relaxed)
                              >> 2 * HD_CHUNK_BITS) + 1) & UINT32_MAX;
    atomic_store_explicit(&c->work, colour << 2 * HD_CHUNK_BITS | (uint64_t)count << HD_CHUNK_BITS,
                          memory_order_release);
    double largest = 0.0;
    long mine = 0;
    for (long taken; (taken = hd_take(c, atomic_load_explicit(&c->work,
                                                              memory_order_acquire))) >= 0;) {
        largest = hd_max(largest, chunk(job, taken));
        mine += 1;
    }
    largest = hd_max(largest, alone(job));
    while (atomic_load_explicit(&c->done, memory_order_acquire) < count - mine)
        hd_relax();
    return hd_max(largest, c->found);
}

#endif
