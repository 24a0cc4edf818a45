/*
 * A C DAQ daemon closing the fts-servo controller's loop: each tick it reads the "ADC" (here
 * the simulated stage, libfts_plant), ticks the controller (libfts_servo) and writes the
 * "DAC". Paced to the wall clock with --realtime, as fast as it can otherwise (lockstep).
 *
 *   daemon DEPLOYMENT [--plant CONFIG] [--ticks N] [--serve PREFIX] [--realtime]
 *
 * Prints the loop's digest (FNV-1a over each tick's seq, gap, accelerometer and command, as
 * `servo run --digest` prints it) and the tick statistics.
 */
#define _POSIX_C_SOURCE 200809L
#include <fts_plant.h>
#include <fts_servo.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* FNV-1a (64-bit) over the little-endian bytes of the tick's words. */
static uint64_t fnv(uint64_t h, uint64_t word) {
    for (int i = 0; i < 8; i++) {
        h ^= (word >> (8 * i)) & 0xff;
        h *= 0x100000001b3ull;
    }
    return h;
}

static uint64_t bits(double x) {
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

static uint64_t now_ns(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (uint64_t)t.tv_sec * 1000000000u + (uint64_t)t.tv_nsec;
}

int main(int argc, char **argv) {
    const char *deployment = NULL, *plant_config = NULL, *prefix = NULL;
    uint64_t ticks = 0;
    int realtime = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--plant") && i + 1 < argc) plant_config = argv[++i];
        else if (!strcmp(argv[i], "--ticks") && i + 1 < argc) ticks = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--serve") && i + 1 < argc) prefix = argv[++i];
        else if (!strcmp(argv[i], "--realtime")) realtime = 1;
        else deployment = argv[i];
    }
    if (!deployment) {
        fprintf(stderr, "usage: %s DEPLOYMENT [--plant CONFIG] [--ticks N] [--serve PREFIX] [--realtime]\n", argv[0]);
        return 2;
    }
    char error[1024];
    fts_servo_abi abi = FTS_SERVO_ABI_INIT;
    fts_servo *servo = NULL;
    if (fts_servo_open(deployment, &abi, &servo, error, sizeof error) != FTS_SERVO_OK) {
        fprintf(stderr, "error: %s\n", error);
        return 2;
    }
    fts_plant *stage = NULL; /* your ADC/DAC driver */
    if (fts_plant_open(plant_config, &stage, error, sizeof error) != FTS_PLANT_OK) {
        fprintf(stderr, "error: %s\n", error);
        fts_servo_close(servo);
        return 2;
    }
    if (prefix && fts_servo_serve(servo, prefix) != FTS_SERVO_OK) {
        fprintf(stderr, "error: %s\n", fts_servo_last_error(servo));
        return 1;
    }
    if (ticks == 0) ticks = fts_plant_ticks(stage);
    const uint64_t period_ns = (uint64_t)(fts_plant_period_s(stage) * 1e9 + 0.5);
    fts_Sensor sample;
    fts_Command command;
    fts_plant_initial(stage, &sample);
    uint64_t digest = 0xcbf29ce484222325ull, start = now_ns() + period_ns;
    int tripped = 0;
    for (uint64_t k = 0; k < ticks; k++) {
        if (realtime) {
            uint64_t deadline = start + k * period_ns;
            while (now_ns() < deadline) {
            }
            sample.published_ns = deadline;
        }
        int r = fts_servo_tick(servo, &sample, &command); /* no allocation, lock or log */
        if (r == FTS_SERVO_TRIPPED && !tripped) {
            tripped = 1;
            fprintf(stderr, "%s\n", fts_servo_last_error(servo));
        }
        digest = fnv(fnv(fnv(fnv(digest, sample.seq), bits(sample.gap_v)), bits(sample.accel_v)), bits(command.dac_v));
        if (fts_plant_step(stage, command.dac_v, &sample, NULL) != FTS_PLANT_OK) break;
        fts_servo_state state;
        if ((k & 2047) == 0 && fts_servo_get_state(servo, &state) == FTS_SERVO_OK && state.stop_cause) break;
    }
    fts_servo_state state;
    fts_servo_get_state(servo, &state);
    printf("digest %016" PRIx64 "\n", digest);
    printf("%" PRIu64 " ticks, %" PRIu64 " saturated, %s, execution p99.99 %.2f us\n",
           state.ticks, state.saturated_ticks,
           state.trip_cause ? "tripped (the cause and tick above)" : "not tripped",
           state.execution.p9999_ns * 1e-3);
    fts_servo_close(servo); /* ends the service: the last telemetry, a final health report */
    fts_plant_close(stage);
    return 0;
}
