/*
 * After fts_servo_open, ticking allocates nothing: malloc and its relatives are interposed
 * here (glibc's __libc_* underneath) and counted through 200 000 timed ticks of the
 * deployment — with CONTROLLER, prepared before and swapped in halfway (fts_servo_swap).
 *
 *   test_alloc DEPLOYMENT [CONTROLLER]
 */
#define _GNU_SOURCE
#include <fts_servo.h>
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

extern void *__libc_malloc(size_t);
extern void *__libc_calloc(size_t, size_t);
extern void *__libc_realloc(void *, size_t);
extern void *__libc_memalign(size_t, size_t);
extern void __libc_free(void *);

static volatile int counting = 0;
static volatile unsigned long calls = 0;

void *malloc(size_t n) {
    if (counting) calls++;
    return __libc_malloc(n);
}
void *calloc(size_t n, size_t m) {
    if (counting) calls++;
    return __libc_calloc(n, m);
}
void *realloc(void *p, size_t n) {
    if (counting) calls++;
    return __libc_realloc(p, n);
}
void free(void *p) {
    if (counting && p) calls++;
    __libc_free(p);
}
int posix_memalign(void **out, size_t align, size_t n) {
    if (counting) calls++;
    *out = __libc_memalign(align, n);
    return *out ? 0 : 12;
}
void *aligned_alloc(size_t align, size_t n) {
    if (counting) calls++;
    return __libc_memalign(align, n);
}

int main(int argc, char **argv) {
    if (argc != 2 && argc != 3) return 2;
    char error[1024];
    fts_servo_abi abi = FTS_SERVO_ABI_INIT;
    fts_servo *h = NULL;
    if (fts_servo_open(argv[1], &abi, &h, error, sizeof error) != FTS_SERVO_OK) {
        fprintf(stderr, "error: %s\n", error);
        return 2;
    }
    /* With a controller file: prepared before counting, swapped in halfway through. */
    fts_servo_prepared *prepared = NULL;
    if (argc == 3) {
        FILE *f = fopen(argv[2], "rb");
        static uint8_t file[65536];
        size_t len = f ? fread(file, 1, sizeof file, f) : 0;
        if (f) fclose(f);
        fts_servo_loader *loader = NULL;
        if (fts_servo_loader_new(h, &loader) != FTS_SERVO_OK ||
            fts_servo_prepare(loader, file, len, &prepared, error, sizeof error) != FTS_SERVO_OK) {
            fprintf(stderr, "error: %s\n", error);
            return 2;
        }
        fts_servo_loader_free(loader);
    }
    int swapped = prepared == NULL;
    fts_Sensor s = {0};
    fts_Command c;
    struct timespec now;
    counting = 1;
    for (unsigned long k = 0; k < 200000; k++) {
        if (k == 100000 && prepared) swapped = fts_servo_swap(h, prepared) == FTS_SERVO_OK;
        clock_gettime(CLOCK_MONOTONIC, &now);
        s.seq = k;
        s.gap_v = 1e-3 * (double)((long)(k % 7) - 3);
        s.published_ns = (uint64_t)now.tv_sec * 1000000000u + (uint64_t)now.tv_nsec;
        fts_servo_tick(h, &s, &c);
    }
    counting = 0;
    fts_servo_prepared_free(prepared);
    fts_servo_close(h);
    printf("%lu heap calls in 200000 ticks%s\n", calls, argc == 3 ? " and a controller swapped in" : "");
    return calls == 0 && swapped ? 0 : 1;
}
