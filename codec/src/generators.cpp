#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>
#include <voxwall/codec/generators.hpp>
#include <voxwall/core/parallel.hpp>

namespace voxwall::codec {
namespace {

// Stores f(x, y, z) in [0, 1] for every voxel of an n^3 grid over [-1, 1]^3.
template <class F>
Volume sampleUnitCube(int n, ScalarType type, F&& f) {
  if (n < 2 || n > 2048) throw std::invalid_argument("generated volume size must be in 2..2048");
  Volume v = Volume::allocate({n, n, n}, type);
  dispatchScalar(type, [&](auto t) {
    using T = decltype(t);
    auto out = v.as<T>();
    const double scale =
        std::is_same_v<T, float> ? 1.0 : (std::is_same_v<T, std::uint8_t> ? 255.0 : 65535.0);
    const double s = std::is_same_v<T, std::int16_t> ? 32767.0 : scale;
    parallelFor(std::size_t(n), 0, [&](std::size_t zi) {
      const double z = -1.0 + 2.0 * double(zi) / (n - 1);
      for (int yi = 0; yi < n; ++yi) {
        const double y = -1.0 + 2.0 * yi / (n - 1);
        for (int xi = 0; xi < n; ++xi) {
          const double x = -1.0 + 2.0 * xi / (n - 1);
          const double value = std::clamp(f(x, y, z), 0.0, 1.0);
          out[v.index(xi, yi, int(zi))] =
              std::is_same_v<T, float> ? T(value) : T(std::lround(value * s));
        }
      }
    });
  });
  v.computeRange();
  return v;
}

}  // namespace

Volume generateMenger(int level) {
  if (level < 0 || level > 7) throw std::invalid_argument("Menger sponge level must be in 0..7");
  int n = 1;
  for (int i = 0; i < level; ++i) n *= 3;
  Volume v = Volume::allocate({n, n, n}, ScalarType::UInt8);
  auto out = v.as<std::uint8_t>();
  parallelFor(std::size_t(n), 0, [&](std::size_t zi) {
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        // Carved when, at some level, at least two of the base-3 digits are the middle one.
        bool solid = true;
        for (int a = x, b = y, c = int(zi); solid && (a || b || c); a /= 3, b /= 3, c /= 3)
          solid = (a % 3 == 1) + (b % 3 == 1) + (c % 3 == 1) < 2;
        out[v.index(x, y, int(zi))] = solid ? 255 : 0;
      }
  });
  v.computeRange();
  return v;
}

Volume generateMarschnerLobb(int n, ScalarType type) {
  constexpr double fM = 6.0, alpha = 0.25, pi = std::numbers::pi;
  return sampleUnitCube(n, type, [&](double x, double y, double z) {
    const double r = std::sqrt(x * x + y * y);
    const double rhoR = std::cos(2.0 * pi * fM * std::cos(pi * r / 2.0));
    return (1.0 - std::sin(pi * z / 2.0) + alpha * (1.0 + rhoR)) / (2.0 * (1.0 + alpha));
  });
}

Volume generateSheppLogan(int n, ScalarType type) {
  // Kak & Slaney's 3D ellipsoids with Toft's modified intensities:
  // intensity, semi-axes a b c, centre x0 y0 z0, Euler angles phi theta psi (degrees, z-x-z).
  static constexpr double kEllipsoids[10][10] = {
      {1.0, 0.6900, 0.920, 0.810, 0, 0, 0, 0, 0, 0},
      {-0.8, 0.6624, 0.874, 0.780, 0, -0.0184, 0, 0, 0, 0},
      {-0.2, 0.1100, 0.310, 0.220, 0.22, 0, 0, -18, 0, 10},
      {-0.2, 0.1600, 0.410, 0.280, -0.22, 0, 0, 18, 0, 10},
      {0.1, 0.2100, 0.250, 0.410, 0, 0.35, -0.15, 0, 0, 0},
      {0.1, 0.0460, 0.046, 0.050, 0, 0.1, 0.25, 0, 0, 0},
      {0.1, 0.0460, 0.046, 0.050, 0, -0.1, 0.25, 0, 0, 0},
      {0.1, 0.0460, 0.023, 0.050, -0.08, -0.605, 0, 0, 0, 0},
      {0.1, 0.0230, 0.023, 0.020, 0, -0.606, 0, 0, 0, 0},
      {0.1, 0.0230, 0.046, 0.020, 0.06, -0.605, 0, 0, 0, 0},
  };
  struct Ellipsoid {
    double value, a, b, c, x0, y0, z0, r[9];
  };
  std::vector<Ellipsoid> ellipsoids;
  for (auto& e : kEllipsoids) {
    const double d2r = std::numbers::pi / 180.0;
    const double phi = e[7] * d2r, theta = e[8] * d2r, psi = e[9] * d2r;
    const double cphi = std::cos(phi), sphi = std::sin(phi), cth = std::cos(theta),
                 sth = std::sin(theta), cpsi = std::cos(psi), spsi = std::sin(psi);
    Ellipsoid el{e[0], e[1], e[2], e[3], e[4], e[5], e[6], {}};
    const double r[9] = {cpsi * cphi - cth * sphi * spsi,
                         cpsi * sphi + cth * cphi * spsi,
                         spsi * sth,
                         -spsi * cphi - cth * sphi * cpsi,
                         -spsi * sphi + cth * cphi * cpsi,
                         cpsi * sth,
                         sth * sphi,
                         -sth * cphi,
                         cth};
    std::copy(r, r + 9, el.r);
    ellipsoids.push_back(el);
  }
  return sampleUnitCube(n, type, [&](double x, double y, double z) {
    double value = 0;
    for (auto& e : ellipsoids) {
      const double px = x - e.x0, py = y - e.y0, pz = z - e.z0;
      const double u = e.r[0] * px + e.r[1] * py + e.r[2] * pz;
      const double v = e.r[3] * px + e.r[4] * py + e.r[5] * pz;
      const double w = e.r[6] * px + e.r[7] * py + e.r[8] * pz;
      if (u * u / (e.a * e.a) + v * v / (e.b * e.b) + w * w / (e.c * e.c) <= 1.0) value += e.value;
    }
    return value;
  });
}

}  // namespace voxwall::codec

namespace voxwall::codec {

Volume generateOrbitingBlobs(int n, int step, int steps, ScalarType type) {
  if (steps < 1 || step < 0 || step >= steps)
    throw std::invalid_argument("step " + std::to_string(step) + " of " + std::to_string(steps) +
                                " steps");
  const double pi = std::numbers::pi;
  const double t = steps > 1 ? double(step) / double(steps - 1) : 0.0;
  const double phase = 2.0 * pi * double(step) / double(steps);
  struct Blob {
    double x, y, z, inverseTwoSigma2, weight;
  };
  Blob blobs[3];
  for (int i = 0; i < 3; ++i) {
    const double angle = phase + 2.0 * pi * i / 3.0;
    const double sigma = 0.12 + 0.08 * t + 0.02 * i;
    blobs[i] = {0.5 * std::cos(angle), 0.5 * std::sin(angle), 0.3 * std::sin(phase + i),
                1.0 / (2.0 * sigma * sigma), 0.9 - 0.15 * i};
  }
  return sampleUnitCube(n, type, [&](double x, double y, double z) {
    const double ring = std::sqrt(x * x + y * y) - 0.85;
    double value = 0.4 * std::exp(-(ring * ring + z * z) / 0.004);
    for (const Blob& b : blobs) {
      const double dx = x - b.x, dy = y - b.y, dz = z - b.z;
      value += b.weight * std::exp(-(dx * dx + dy * dy + dz * dz) * b.inverseTwoSigma2);
    }
    return value;
  });
}

}  // namespace voxwall::codec
