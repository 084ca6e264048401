#ifndef KNOTMM_STEPPER_NOISE_STREAM_H_
#define KNOTMM_STEPPER_NOISE_STREAM_H_

#include <cstdint>
#include <iosfwd>

namespace KnotMM {

/**
 * The stepper's random numbers. A run's stream is counter based (Philox.h): the k-th draw of
 * normals is a pure function of the key (from the seed) and k, so a backend makes it where its
 * vectors live (the device kernels draw on the device) and the noise does not depend on the
 * platform; its state is the key and the draw counter.
 *
 * The sequential stream of the builds before stepper layout 6, xoshiro256** with
 * Marsaglia-polar normals drawn on the host, is kept for two uses: a checkpoint of layout 5
 * or older continues with it (so an old run resumes the run it was), and fixed start vectors
 * (rkc2's power iteration) that must not change.
 */
class NoiseStream {
public:
    /** A counter-based stream keyed by `seed`, at its first draw. */
    void seed(uint64_t seed);
    /** The sequential stream of layouts 2-5, filled from `seed` by splitmix64. */
    void seedSequential(uint64_t seed);
    bool counterBased() const { return counter; }
    uint64_t key() const { return counterKey; }
    /** Counter based: the index of the next draw, and count it as drawn. */
    uint64_t takeDraw() { return draws++; }
    /** out[0..count) = the next draw's standard normals, on the host (either kind of stream). */
    void fill(double* out, int count);
    /** Sequential stream: one standard normal. */
    double sequentialNormal();

    /** The sequential state (the field of layouts 2-5, zeros for a counter-based stream). */
    void writeSequential(std::ostream& stream) const;
    void readSequential(std::istream& stream);
    /** The counter-based state (appended by layout 6). */
    void writeCounter(std::ostream& stream) const;
    void readCounter(std::istream& stream);

private:
    uint64_t next();
    double uniform();
    bool counter = true;
    uint64_t counterKey = 0, draws = 0;
    uint64_t s[4] = {0, 0, 0, 0};
    bool haveSpare = false;
    double spare = 0.0;
};

} // namespace KnotMM

#endif
