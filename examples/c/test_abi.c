/*
 * libfts_servo's C ABI on bad input: each case returns its documented code and a message that
 * names what was wrong; nothing crashes (CI runs this under valgrind); a tripped loop keeps its
 * safe state until fts_servo_reset.
 *
 *   test_abi DIR   with DIR/deploy.toml (servo deploy), DIR/pid.toml (servo tune, this plant),
 *                  DIR/heavy.toml (servo tune --mass heavy), DIR/h2_20k.toml (servo synth h2
 *                  --rate 20000), DIR/unchecked.toml (a [controller] table with no [stability])
 */
#include <fts_servo.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int failures = 0;

#define EXPECT(cond, ...)                                     \
    do {                                                      \
        if (!(cond)) {                                        \
            failures++;                                       \
            fprintf(stderr, "FAILED %s:%d: ", __FILE__, __LINE__); \
            fprintf(stderr, __VA_ARGS__);                     \
            fprintf(stderr, "\n");                            \
        }                                                     \
    } while (0)

static char *slurp(const char *dir, const char *name, size_t *len) {
    char path[4096];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        exit(2);
    }
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *text = malloc((size_t)n + 1);
    if (fread(text, 1, (size_t)n, f) != (size_t)n) exit(2);
    text[n] = 0;
    fclose(f);
    if (len) *len = (size_t)n;
    return text;
}

/* The deployment text with the first `from` replaced by `to`. */
static char *edited(const char *text, const char *from, const char *to) {
    const char *at = strstr(text, from);
    if (!at) {
        fprintf(stderr, "'%s' not in the deployment\n", from);
        exit(2);
    }
    size_t head = (size_t)(at - text), n = strlen(text) - strlen(from) + strlen(to);
    char *out = malloc(n + 1);
    memcpy(out, text, head);
    strcpy(out + head, to);
    strcat(out, at + strlen(from));
    return out;
}

static int load_file(fts_servo *h, const char *dir, const char *name) {
    size_t len;
    char *bytes = slurp(dir, name, &len);
    int r = fts_servo_load(h, (const uint8_t *)bytes, len);
    free(bytes);
    return r;
}

int main(int argc, char **argv) {
    if (argc != 2) {
        fprintf(stderr, "usage: %s DIR\n", argv[0]);
        return 2;
    }
    const char *dir = argv[1];
    char *deployment = slurp(dir, "deploy.toml", NULL);
    fts_servo_abi abi = FTS_SERVO_ABI_INIT;
    char error[1024];
    fts_servo *h = NULL;

    /* Null pointers. */
    EXPECT(fts_servo_open_toml(NULL, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_NULL && h == NULL,
           "null text");
    EXPECT(strstr(error, "text is a null pointer"), "message: %s", error);
    EXPECT(fts_servo_open_toml(deployment, NULL, &h, error, sizeof error) == FTS_SERVO_ERR_NULL, "null abi");
    EXPECT(fts_servo_open_toml(deployment, &abi, NULL, error, sizeof error) == FTS_SERVO_ERR_NULL, "null out");
    EXPECT(fts_servo_tick(NULL, NULL, NULL) == FTS_SERVO_ERR_NULL, "null handle");
    EXPECT(strstr(fts_servo_last_error(NULL), "null"), "null handle's message");
    fts_servo_close(NULL);

    /* Another ABI version, another struct size. */
    fts_servo_abi old = abi;
    old.abi_version = FTS_SERVO_ABI_VERSION + 1;
    EXPECT(fts_servo_open_toml(deployment, &old, &h, error, sizeof error) == FTS_SERVO_ERR_ABI, "abi version");
    EXPECT(strstr(error, "ABI mismatch"), "message: %s", error);
    old = abi;
    old.sensor_size -= 8;
    EXPECT(fts_servo_open_toml(deployment, &old, &h, error, sizeof error) == FTS_SERVO_ERR_ABI, "sensor size");

    /* A value out of range: named by key and allowed range. */
    char *bad = edited(deployment, "limit_v = 10.0", "limit_v = 12.0");
    EXPECT(fts_servo_open_toml(bad, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_CONFIG && h == NULL,
           "limit_v out of range");
    EXPECT(strstr(error, "controller.limit_v") && strstr(error, "(0, 10] V"), "message: %s", error);
    free(bad);
    /* A gain or the stability record edited after the check: refused, naming what changed. */
    bad = edited(deployment, "kp = ", "kp = 2.0 # ");
    EXPECT(fts_servo_open_toml(bad, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_CONFIG && h == NULL,
           "an edited gain");
    EXPECT(strstr(error, "controller.stability.sha256.controller") && strstr(error, "does not match"),
           "message: %s", error);
    free(bad);
    bad = edited(deployment, "unstable_above = ", "unstable_above = 1000.0 # ");
    EXPECT(fts_servo_open_toml(bad, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_CONFIG && h == NULL,
           "an edited stability record");
    EXPECT(strstr(error, "controller.stability.sha256.record"), "message: %s", error);
    free(bad);
    /* Text that is not UTF-8 is the content's fault, not a null pointer's. */
    bad = edited(deployment, "limit_v = 10.0", "limit_v = 10.0 # \xff");
    EXPECT(fts_servo_open_toml(bad, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_CONFIG && h == NULL,
           "not UTF-8");
    EXPECT(strstr(error, "not UTF-8"), "message: %s", error);
    free(bad);
    char path[4096];
    snprintf(path, sizeof path, "%s/missing.toml", dir);
    EXPECT(fts_servo_open(path, &abi, &h, error, sizeof error) == FTS_SERVO_ERR_CONFIG, "missing file");
    EXPECT(strstr(error, "missing.toml"), "message: %s", error);

    /* The good deployment. */
    snprintf(path, sizeof path, "%s/deploy.toml", dir);
    EXPECT(fts_servo_open(path, &abi, &h, error, sizeof error) == FTS_SERVO_OK && h, "open: %s", error);
    fts_Sensor s = {0};
    fts_Command c;
    fts_Telemetry t;
    EXPECT(fts_servo_telemetry(h, &t) == FTS_SERVO_ERR_STATE, "telemetry before a tick");
    EXPECT(fts_servo_tick(h, NULL, &c) == FTS_SERVO_ERR_NULL, "null sample");
    for (uint64_t k = 0; k < 100; k++) {
        s.seq = k;
        EXPECT(fts_servo_tick(h, &s, &c) == FTS_SERVO_OK, "tick %llu", (unsigned long long)k);
    }
    EXPECT(fts_servo_telemetry(h, &t) == FTS_SERVO_OK && t.seq == 99, "telemetry");

    /* Gains: inside the checked range applied, outside refused with the range. */
    EXPECT(fts_servo_set_gain(h, 0.8) == FTS_SERVO_OK, "gain 0.8");
    EXPECT(fts_servo_set_gain(h, 100.0) == FTS_SERVO_ERR_MARGIN, "gain 100");
    EXPECT(strstr(fts_servo_last_error(h), "allowed"), "message: %s", fts_servo_last_error(h));
    EXPECT(fts_servo_set_gain(h, NAN) == FTS_SERVO_ERR_MARGIN, "gain NaN");

    /* Controllers: another plant, another rate, unchecked — refused; this plant's taken. */
    EXPECT(load_file(h, dir, "heavy.toml") == FTS_SERVO_ERR_PROVENANCE, "heavy: %s", fts_servo_last_error(h));
    EXPECT(strstr(fts_servo_last_error(h), "stage heavy"), "message: %s", fts_servo_last_error(h));
    EXPECT(load_file(h, dir, "h2_20k.toml") == FTS_SERVO_ERR_PROVENANCE, "20 kHz: %s", fts_servo_last_error(h));
    EXPECT(strstr(fts_servo_last_error(h), "20000 Hz"), "message: %s", fts_servo_last_error(h));
    EXPECT(load_file(h, dir, "unchecked.toml") == FTS_SERVO_ERR_MARGIN, "unchecked: %s", fts_servo_last_error(h));
    EXPECT(strstr(fts_servo_last_error(h), "stability"), "message: %s", fts_servo_last_error(h));
    EXPECT(fts_servo_load(h, (const uint8_t *)"not toml [", 10) == FTS_SERVO_ERR_CONFIG, "not TOML");
    /* A file beyond what a controller file may be is refused before it is read. */
    size_t huge_len = 64u << 20;
    uint8_t *huge = calloc(huge_len, 1);
    EXPECT(fts_servo_load(h, huge, huge_len) == FTS_SERVO_ERR_CONFIG, "64 MB");
    EXPECT(strstr(fts_servo_last_error(h), "more than"), "message: %s", fts_servo_last_error(h));
    free(huge);
    /* A tuned file whose gain was edited after its check: refused, naming the record. */
    size_t pid_len;
    char *pid = slurp(dir, "pid.toml", &pid_len);
    char *pid_edited = edited(pid, "kp = ", "kp = 2.0 # ");
    EXPECT(fts_servo_load(h, (const uint8_t *)pid_edited, strlen(pid_edited)) == FTS_SERVO_ERR_MARGIN,
           "an edited tuned gain: %s", fts_servo_last_error(h));
    EXPECT(strstr(fts_servo_last_error(h), "controller.stability.sha256.controller"), "message: %s",
           fts_servo_last_error(h));
    free(pid_edited);
    free(pid);
    EXPECT(load_file(h, dir, "pid.toml") == FTS_SERVO_OK, "pid: %s", fts_servo_last_error(h));
    for (uint64_t k = 100; k < 200; k++) {
        s.seq = k;
        fts_servo_tick(h, &s, &c);
    }
    fts_servo_state state;
    EXPECT(fts_servo_get_state(h, &state) == FTS_SERVO_OK && state.handovers == 1 && state.gain_scale == 0.8,
           "state after the load");

    /* In two halves: checked and built by a loader (on any thread), swapped in between ticks
     * without allocating; the replaced controller leaves in the prepared handle. */
    fts_servo_loader *loader = NULL;
    fts_servo_prepared *prepared = NULL, *refused = NULL;
    EXPECT(fts_servo_loader_new(h, &loader) == FTS_SERVO_OK && loader != NULL, "loader");
    EXPECT(fts_servo_prepare(loader, (const uint8_t *)"not toml [", 10, &refused, error, sizeof error) ==
                   FTS_SERVO_ERR_CONFIG &&
               refused == NULL,
           "prepare: not TOML");
    size_t heavy_len;
    char *heavy = slurp(dir, "heavy.toml", &heavy_len);
    EXPECT(fts_servo_prepare(loader, (const uint8_t *)heavy, heavy_len, &refused, error, sizeof error) ==
                   FTS_SERVO_ERR_PROVENANCE,
           "prepare: another stage: %s", error);
    EXPECT(strstr(error, "stage heavy"), "message: %s", error);
    free(heavy);
    size_t again_len;
    char *again = slurp(dir, "pid.toml", &again_len);
    EXPECT(fts_servo_prepare(loader, (const uint8_t *)again, again_len, &prepared, error, sizeof error) ==
               FTS_SERVO_OK,
           "prepare: %s", error);
    free(again);
    fts_servo_loader_free(loader);
    EXPECT(fts_servo_swap(h, prepared) == FTS_SERVO_OK, "swap: %s", fts_servo_last_error(h));
    EXPECT(fts_servo_swap(h, prepared) == FTS_SERVO_ERR_STATE, "a second swap of the same");
    EXPECT(strstr(fts_servo_last_error(h), "swapped in already"), "message: %s", fts_servo_last_error(h));
    for (uint64_t k = 200; k < 210; k++) {
        s.seq = k;
        fts_servo_tick(h, &s, &c);
    }
    fts_servo_prepared_free(prepared);
    EXPECT(fts_servo_get_state(h, &state) == FTS_SERVO_OK && state.handovers == 2, "state after the swap");
    EXPECT(fts_servo_swap(h, NULL) == FTS_SERVO_ERR_NULL, "swap of null");

    /* A NaN reading trips; the safe state (0 V) holds, tick after tick, until reset. */
    s.seq = 210;
    s.gap_v = NAN;
    EXPECT(fts_servo_tick(h, &s, &c) == FTS_SERVO_TRIPPED && c.dac_v == 0.0, "NaN trips");
    EXPECT(strstr(fts_servo_last_error(h), "non-finite"), "message: %s", fts_servo_last_error(h));
    s.gap_v = 0.0;
    for (uint64_t k = 211; k < 300; k++) {
        s.seq = k;
        EXPECT(fts_servo_tick(h, &s, &c) == FTS_SERVO_TRIPPED && c.dac_v == 0.0 && (c.flags & FTS_FLAG_TRIPPED),
               "safe state at %llu", (unsigned long long)k);
    }
    EXPECT(fts_servo_get_state(h, &state) == FTS_SERVO_OK && state.trip_cause == FTS_FLAG_TRIP_NOT_FINITE &&
               state.trip_tick == 210,
           "trip in the state");
    EXPECT(fts_servo_reset(h) == FTS_SERVO_OK, "reset");
    s.seq = 300;
    EXPECT(fts_servo_tick(h, &s, &c) == FTS_SERVO_OK && !(c.flags & FTS_FLAG_TRIPPED), "re-armed");
    fts_servo_close(h);
    free(deployment);
    printf("%s\n", failures ? "FAILED" : "every bad input refused with its code and message");
    return failures ? 1 : 0;
}
