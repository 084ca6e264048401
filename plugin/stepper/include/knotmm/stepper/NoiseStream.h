#ifndef KNOTMM_STEPPER_NOISE_STREAM_H_
#define KNOTMM_STEPPER_NOISE_STREAM_H_

#include <cstdint>
#include <iosfwd>

namespace KnotMM {

/**
 * The stepper's random numbers: xoshiro256** with Marsaglia-polar normals. Drawn on the host
 * whatever the platform, so a run's noise does not depend on where its forces are computed;
 * its whole state goes into checkpoints.
 */
class NoiseStream {
public:
    /** Fill the state from `seed` by splitmix64 (never all zero). */
    void seed(uint64_t seed);
    uint64_t next();
    /** Uniform in [0, 1). */
    double uniform();
    /** Standard normal. */
    double normal();
    void write(std::ostream& stream) const;
    void read(std::istream& stream);

private:
    uint64_t s[4] = {0, 0, 0, 0};
    bool haveSpare = false;
    double spare = 0.0;
};

} // namespace KnotMM

#endif
