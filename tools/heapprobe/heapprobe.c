/* synth's heap probe (synth.heapprobe): loaded with LD_PRELOAD, it catches a write into heap
 * memory after the memory was freed, and says which library freed the block and which bytes
 * changed.
 *
 * free() does not give a block back to malloc at once: it fills the block's first PROBE_FILL
 * bytes with 0xA5 and keeps it in a ring of the last SYNTH_HEAPPROBE_BLOCKS blocks (default
 * 4096; blocks larger than SYNTH_HEAPPROBE_MAX_BYTES, default 1 MiB, are freed at once; the
 * oldest go early while the ring holds more than SYNTH_HEAPPROBE_MAX_HELD bytes, 256 MiB). When
 * a block leaves the ring (and for every block still in it when the process exits) its filled
 * bytes are checked: any byte that is no longer 0xA5 was written after the block was freed,
 * and a line starting "synth heap probe:" goes to stderr. Nothing else changes: the program's
 * results are the same, it uses more memory (the ring) and a little more time.
 *
 * Why (issue 16): render processes died in glibc's malloc (2026-11-23, 4 segfaults) reading
 * through a free chunk's back pointer whose low 32 bits had been set to zero: a 4-byte zero
 * written at +8 of a freed block, which glibc only trips over much later and only when the
 * chunk sits in a doubly linked bin. The probe reports such a write on the next ~4096 frees,
 * whatever bin the block would have gone to. */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <malloc.h>
#include <pthread.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/prctl.h>

#define PROBE_FILL 256
#define PROBE_BYTE 0xA5
#define RING_MAX 65536

struct held {
    unsigned char *p;
    size_t n;
    void *by;
    char thread[16];
};

static void (*real_free)(void *);
static struct held ring[RING_MAX];
static size_t ring_len, ring_used, ring_next;
static size_t max_bytes = 1 << 20;
static size_t max_held = (size_t)256 << 20, held;
static volatile int ring_lock, ready;
static long reports;

static void lock(void) { while (__sync_lock_test_and_set(&ring_lock, 1)) sched_yield(); }
static void unlock(void) { __sync_lock_release(&ring_lock); }

static __thread char thread_name[16];
static __thread int named;

static void before_fork(void) { lock(); }
static void after_fork(void) { unlock(); }

static void setup(void) {
    if (ready)
        return;
    pthread_atfork(before_fork, after_fork, after_fork);
    real_free = (void (*)(void *))dlsym(RTLD_NEXT, "free");
    const char *s = getenv("SYNTH_HEAPPROBE_BLOCKS");
    ring_len = s ? (size_t)strtoul(s, NULL, 10) : 4096;
    if (ring_len > RING_MAX)
        ring_len = RING_MAX;
    s = getenv("SYNTH_HEAPPROBE_MAX_BYTES");
    if (s)
        max_bytes = (size_t)strtoul(s, NULL, 10);
    s = getenv("SYNTH_HEAPPROBE_MAX_HELD");
    if (s)
        max_held = (size_t)strtoul(s, NULL, 10);
    ready = 1;
}

static void check(const struct held *h) {
    size_t m = h->n < PROBE_FILL ? h->n : PROBE_FILL;
    for (size_t k = 0; k < m; k++) {
        if (h->p[k] == PROBE_BYTE)
            continue;
        size_t e = k;
        while (e < m && h->p[e] != PROBE_BYTE)
            e++;
        char hex[2 * 32 + 1] = {0};
        for (size_t j = k; j < e && j < k + 32; j++)
            snprintf(hex + 2 * (j - k), 3, "%02x", h->p[j]);
        Dl_info di = {0};
        dladdr(h->by, &di);
        __sync_fetch_and_add(&reports, 1);
        fprintf(stderr,
                "synth heap probe: bytes +%zu..+%zu of a %zu-byte block freed by %s+%#lx "
                "(thread %s) were written after it was freed: %s\n",
                k, e - 1, h->n, di.dli_fname ? di.dli_fname : "?",
                (unsigned long)((uintptr_t)h->by - (uintptr_t)di.dli_fbase), h->thread, hex);
        k = e;
    }
}

void free(void *p) {
    setup();
    if (p == NULL || ring_len == 0 || real_free == NULL) {
        if (real_free)
            real_free(p);
        return;
    }
    size_t n = malloc_usable_size(p);
    if (n > max_bytes) {
        real_free(p);
        return;
    }
    struct held h = {(unsigned char *)p, n, __builtin_return_address(0), {0}};
    if (!named) {
        prctl(PR_GET_NAME, thread_name, 0, 0, 0);
        named = 1;
    }
    memcpy(h.thread, thread_name, sizeof h.thread);
    memset(p, PROBE_BYTE, n < PROBE_FILL ? n : PROBE_FILL);
    /* the oldest blocks go (checked, then freed) while the ring is full or would hold more
       than max_held bytes */
    for (;;) {
        struct held out;
        lock();
        if (ring_used == 0 || (ring_used < ring_len && held + n <= max_held)) {
            ring[ring_next] = h;
            ring_next = (ring_next + 1) % ring_len;
            ring_used++;
            held += n;
            unlock();
            return;
        }
        out = ring[(ring_next + ring_len - ring_used) % ring_len];
        held -= out.n;
        ring_used--;
        unlock();
        check(&out);
        real_free(out.p);
    }
}

__attribute__((destructor)) static void finish(void) {
    lock();
    for (size_t k = 0; k < ring_used; k++)  /* the held blocks, oldest first */
        check(&ring[(ring_next + ring_len - ring_used + k) % ring_len]);
    unlock();
    if (getenv("SYNTH_HEAPPROBE_SUMMARY"))
        fprintf(stderr, "synth heap probe: %ld writes after free reported\n", reports);
}
