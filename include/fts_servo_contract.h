/*
 * fts-servo sample contract, version 6: the messages plant, controller and recorder exchange
 * over iceoryx2 (publish-subscribe services `fts-servo/<prefix>/<leaf>`), for a DAQ daemon
 * written in C or C++ (iceoryx2's C/C++ bindings).
 *
 * Mirrors crates/daq-io/src/contract.rs field for field (#[repr(C)], no implicit padding).
 * CI compiles assertions of every size and offset generated from the Rust types
 * (crates/daq-io/tests/c_header.rs), so this file cannot drift from them.
 *
 * To interoperate, a peer must:
 *   - use the iceoryx2 type names "fts_servo::v6::<Type>" (FTS_SERVO_TYPE_NAME below) for
 *     the services of its leaf (sensor: fts_Sensor, command: fts_Command, telemetry:
 *     fts_TelemetryBlock, truth: fts_TruthBlock, control: fts_Control, ack: fts_Ack,
 *     health: fts_Health, controller_load: fts_ControllerLoad, recorded: fts_Health);
 *   - in lockstep, a plant that waits for a recorder holds its ticks while the recorder's
 *     `recorded` report (role FTS_ROLE_RECORDER, ticks taken) lags by half the truth queue,
 *     so that a lockstep recording loses nothing (see crates/daq-io/src/recorder_pace.rs);
 *   - name its iceoryx2 node "fts-servo/v6/<prefix>/<role>" (role: plant, controller,
 *     recorder, …): peers refuse a run whose nodes speak another contract version, naming both.
 * Units are SI; times in s; flags are the FTS_FLAG_* bits.
 */
#ifndef FTS_SERVO_CONTRACT_H
#define FTS_SERVO_CONTRACT_H

#include <stdint.h>

#define FTS_SERVO_CONTRACT_VERSION 6
#define FTS_SERVO_TYPE_NAME(type) "fts_servo::v6::" #type
#define FTS_SERVO_BLOCK_TICKS 64
#define FTS_SERVO_MAX_LOAD_BYTES 65536

/* Status bits of every flags word. 0-7 plant (converters), 8-15 controller, 16+ transport. */
#define FTS_FLAG_GAP_CLIPPED (1u << 0)
#define FTS_FLAG_ACCEL_CLIPPED (1u << 1)
#define FTS_FLAG_DAC_CLIPPED (1u << 2)
#define FTS_FLAG_COMMAND_NOT_FINITE (1u << 3)
#define FTS_FLAG_SATURATED (1u << 8)
#define FTS_FLAG_TRIPPED (1u << 9)
#define FTS_FLAG_TRIP_FOLLOWING_ERROR (1u << 10)
#define FTS_FLAG_TRIP_SENSOR_RANGE (1u << 11)
#define FTS_FLAG_TRIP_SATURATION (1u << 12)
#define FTS_FLAG_TRIP_NOT_FINITE (1u << 13)
#define FTS_FLAG_TRIP_REFERENCE_FAULT (1u << 14)
#define FTS_FLAG_END (1u << 16)
#define FTS_FLAG_FAULT_PEER_LOST (1u << 17)
#define FTS_FLAG_OVERRUN (1u << 18)
#define FTS_FLAG_FAULT_CONTROLLER (1u << 19)
#define FTS_FLAG_FAULT_OVERRUN_BUDGET (1u << 20) /* the controller kept answering late */
#define FTS_FLAG_NO_TELEMETRY (1u << 21) /* recordings: truth only, the telemetry was lost */
#define FTS_FLAG_NO_TRUTH (1u << 22) /* truth records: the plant knows no truth (real hardware) */

/* Control-plane commands (fts_Control.command). */
#define FTS_COMMAND_STOP 1u
#define FTS_COMMAND_SET_GAIN_SCALE 2u
#define FTS_COMMAND_START 3u
#define FTS_COMMAND_LOAD_CONTROLLER 4u /* fts_Ack.command answering an fts_ControllerLoad */

/* Acknowledgement status (fts_Ack.status). */
#define FTS_ACK_APPLIED 1u
#define FTS_ACK_REFUSED_MARGIN 2u
#define FTS_ACK_REFUSED_INVALID 3u
#define FTS_ACK_REFUSED_PROVENANCE 4u

/* Roles (fts_Health.role, fts_Ack.role) and states (fts_Health.state). */
#define FTS_ROLE_PLANT 1u
#define FTS_ROLE_CONTROLLER 2u
#define FTS_ROLE_RECORDER 3u
#define FTS_STATE_WAITING 1u
#define FTS_STATE_RUNNING 2u
#define FTS_STATE_DONE 3u
#define FTS_STATE_FAULTED 4u
#define FTS_STATE_HELD_FOR_RECORDER 5u /* lockstep: waiting for the recorder to catch up */

/* Why a run was stopped early (fts_Health.stop_cause; 1-127: a signal number). */
#define FTS_STOP_CAUSE_NONE 0u
#define FTS_STOP_CAUSE_CONTROL (1u << 16)
#define FTS_STOP_CAUSE_WRITE_FAILED (1u << 17)
#define FTS_STOP_CAUSE_TRIPPED (1u << 18)

/* Plant -> controller, once per tick: the readings at the start of tick seq. */
typedef struct fts_Sensor {
    uint64_t seq;           /* tick index */
    double time_s;          /* run time, s (0 at the first reading) */
    double gap_v;           /* gap sensor reading, V */
    double accel_v;         /* accelerometer reading, V */
    uint64_t encoder_count; /* spindle encoder pulses since the start */
    uint32_t flags;
    uint32_t reserved;
    uint64_t run_id;        /* the run's identity: random, nonzero, the same on every sample */
    uint64_t published_ns;  /* CLOCK_MONOTONIC when published, ns (0: unknown) */
} fts_Sensor;

/* Controller -> plant, once per tick: the DAC command for tick seq. */
typedef struct fts_Command {
    uint64_t seq;  /* the echoed fts_Sensor.seq */
    double dac_v;  /* V */
    uint32_t flags;
    uint32_t reserved;
} fts_Command;

/* What the controller saw and did on one tick: the reading it acted on (sample seq), the
 * tick's reference, the errors it formed and its command (contract v6; v5 paired the
 * reference with the next reading). */
typedef struct fts_Telemetry {
    uint64_t seq;
    double time_s;             /* the reading's time (start of the tick), run time, s */
    double reference_m;        /* the tick's reference, m */
    double measured_m;         /* the reading the tick acted on, m */
    double following_error_m;  /* reference - measured, m */
    double controller_error_m; /* shaped reference (smoothing, ZPETC) - measured, m */
    double control_v;          /* the tick's command, V */
    double accel_m_s2;         /* m/s^2 */
    uint32_t flags;
    uint32_t reserved;
} fts_Telemetry;

/* What really happened in the plant over one tick (a simulator; a DAQ daemon may send zeros). */
typedef struct fts_Truth {
    uint64_t seq;
    double time_s;          /* end of the tick, run time, s */
    double tool_m;          /* m */
    double gap_m;           /* m */
    double motor_force_n;   /* N */
    double cutting_force_n; /* N */
    double coil_current_a;  /* A */
    double current_noise_a; /* A */
    double base_m;          /* m */
    double sensor_noise_v;  /* V */
    double dac_v;           /* V */
    uint32_t flags;
    uint32_t reserved;
} fts_Truth;

/* Up to FTS_SERVO_BLOCK_TICKS consecutive records (count valid; FTS_FLAG_END on the last). */
typedef struct fts_TelemetryBlock {
    uint64_t block;
    uint32_t count;
    uint32_t flags;
    uint64_t run_id; /* fts_Sensor.run_id of the run */
    fts_Telemetry ticks[FTS_SERVO_BLOCK_TICKS];
} fts_TelemetryBlock;

typedef struct fts_TruthBlock {
    uint64_t block;
    uint32_t count;
    uint32_t flags;
    uint64_t run_id; /* fts_Sensor.run_id of the run */
    fts_Truth ticks[FTS_SERVO_BLOCK_TICKS];
} fts_TruthBlock;

/* Anyone -> plant and controller. */
typedef struct fts_Control {
    uint32_t command; /* FTS_COMMAND_* */
    uint32_t reserved;
    double value;     /* argument, unit per command */
    uint64_t id;      /* echoed by the fts_Ack (0: none wanted) */
} fts_Control;

/* Controller or plant -> anyone: what was done with an fts_Control. */
typedef struct fts_Ack {
    uint64_t id;
    uint64_t tick;      /* applied (or seen) at this tick */
    double value;       /* the request's value */
    double low;         /* lowest value allowed */
    double high;        /* highest value allowed */
    double unstable_at; /* gain scale at which the loop goes unstable (0: n/a) */
    uint32_t command;
    uint32_t status;    /* FTS_ACK_* */
    uint32_t role;      /* FTS_ROLE_* */
    uint32_t reserved;
} fts_Ack;

/* Percentiles of a per-tick time in ns (round trip, start lateness, execution time). */
typedef struct fts_Latency {
    uint64_t count;
    uint64_t min_ns;
    uint64_t p50_ns;
    uint64_t p99_ns;
    uint64_t p999_ns;
    uint64_t p9999_ns;
    uint64_t max_ns;
} fts_Latency;

/* A process's periodic status (every 2048 ticks and once at the end). */
typedef struct fts_Health {
    uint32_t role;
    uint32_t state;
    uint64_t ticks;
    uint64_t overruns;
    uint32_t faults;     /* sticky FTS_FLAG_* fault bits */
    uint32_t stop_cause; /* FTS_STOP_CAUSE_* or a signal number */
    double wall_s;
    fts_Latency latency;   /* plant: round trip sensor -> command */
    fts_Latency lateness;  /* tick start after its deadline (controller: after publication) */
    fts_Latency execution; /* per-tick execution time (TET) */
} fts_Health;

/* Anyone -> controller: a controller file (or [controller] config fragment, UTF-8 TOML) to swap
 * in while the loop runs; answered by an fts_Ack with command FTS_COMMAND_LOAD_CONTROLLER. */
typedef struct fts_ControllerLoad {
    uint64_t id;  /* request id the fts_Ack echoes (nonzero) */
    uint32_t len; /* bytes of data used */
    uint32_t reserved;
    uint8_t data[FTS_SERVO_MAX_LOAD_BYTES];
} fts_ControllerLoad;

#endif /* FTS_SERVO_CONTRACT_H */
