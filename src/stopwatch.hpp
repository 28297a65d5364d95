#pragma once
// Wall time of the detector's stages, for DetectionTiming.
#include <chrono>

namespace binpose {

using Clock = std::chrono::steady_clock;

/// Milliseconds since t0.
inline double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

}  // namespace binpose
