// The C daemon's loop in C++17: the handles owned by RAII wrappers, errors as exceptions,
// the same digest (so CI checks that both languages close the same loop as `servo run`).
//
//   daemon_cpp DEPLOYMENT [PLANT_CONFIG]
#include <fts_plant.h>
#include <fts_servo.h>

#include <cinttypes>
#include <cstdio>
#include <cstring>
#include <memory>
#include <stdexcept>
#include <string>

namespace {

struct CloseServo {
    void operator()(fts_servo *h) const { fts_servo_close(h); }
};
struct ClosePlant {
    void operator()(fts_plant *h) const { fts_plant_close(h); }
};

/// The controller: opened from a deployment, closed when it goes out of scope.
class Servo {
public:
    explicit Servo(const std::string &deployment) {
        char error[1024];
        const fts_servo_abi abi = FTS_SERVO_ABI_INIT;
        fts_servo *h = nullptr;
        if (fts_servo_open(deployment.c_str(), &abi, &h, error, sizeof error) != FTS_SERVO_OK) {
            throw std::runtime_error(error);
        }
        handle_.reset(h);
    }
    /// One tick (real-time safe); true while the loop is not tripped.
    bool tick(const fts_Sensor &sample, fts_Command &command) noexcept {
        return fts_servo_tick(handle_.get(), &sample, &command) == FTS_SERVO_OK;
    }
    fts_servo_state state() const {
        fts_servo_state s{};
        fts_servo_get_state(handle_.get(), &s);
        return s;
    }

private:
    std::unique_ptr<fts_servo, CloseServo> handle_;
};

/// The simulated stage (a lab's ADC/DAC driver in its place).
class Plant {
public:
    explicit Plant(const char *config) {
        char error[1024];
        fts_plant *h = nullptr;
        if (fts_plant_open(config, &h, error, sizeof error) != FTS_PLANT_OK) {
            throw std::runtime_error(error);
        }
        handle_.reset(h);
    }
    fts_Sensor initial() {
        fts_Sensor s{};
        fts_plant_initial(handle_.get(), &s);
        return s;
    }
    bool step(double dac_v, fts_Sensor &sample) {
        return fts_plant_step(handle_.get(), dac_v, &sample, nullptr) == FTS_PLANT_OK;
    }
    std::uint64_t ticks() const { return fts_plant_ticks(handle_.get()); }

private:
    std::unique_ptr<fts_plant, ClosePlant> handle_;
};

std::uint64_t fnv(std::uint64_t h, std::uint64_t word) {
    for (int i = 0; i < 8; ++i) {
        h ^= (word >> (8 * i)) & 0xffu;
        h *= 0x100000001b3ull;
    }
    return h;
}

std::uint64_t bits(double x) {
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
}

}  // namespace

int main(int argc, char **argv) {
    if (argc < 2) {
        std::fprintf(stderr, "usage: %s DEPLOYMENT [PLANT_CONFIG]\n", argv[0]);
        return 2;
    }
    try {
        Servo servo(argv[1]);
        Plant stage(argc > 2 ? argv[2] : nullptr);
        fts_Sensor sample = stage.initial();
        fts_Command command{};
        std::uint64_t digest = 0xcbf29ce484222325ull;
        for (std::uint64_t k = 0; k < stage.ticks(); ++k) {
            servo.tick(sample, command);
            digest = fnv(fnv(fnv(fnv(digest, sample.seq), bits(sample.gap_v)), bits(sample.accel_v)),
                         bits(command.dac_v));
            if (!stage.step(command.dac_v, sample)) break;
        }
        std::printf("digest %016" PRIx64 "\n", digest);
        std::printf("%" PRIu64 " ticks\n", servo.state().ticks);
    } catch (const std::exception &e) {
        std::fprintf(stderr, "error: %s\n", e.what());
        return 2;
    }
    return 0;
}
