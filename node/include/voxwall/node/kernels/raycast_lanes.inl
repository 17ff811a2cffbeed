// The per-ray code over a lane type L (raycast.hpp: ScalarLanes, and the CPU's SIMD lanes):
// ray generation, ray/box entry, the ray march with empty-space skipping, shading and
// compositing. Included on purpose more than once, so no include guard:
// - by raycast.hpp, inside namespace voxwall::node::kernels (CUDA and the CPU's one-ray path);
// - by node/src/cpu_view_targets.hpp once per SIMD target, inside Highway's target region, so
//   that this code is compiled for that target's instruction set. GCC gives a template the target
//   of the place that defines it, not of the place that instantiates it: defined once, outside
//   the region, the SIMD instantiations would not compile unless the whole build targeted the
//   best instruction set (-march=native), and the binary would not run the best one of each CPU.
// The functions are static members of one struct, so that they call each other by class member
// lookup, never by argument-dependent lookup into the other copy's namespace. The includer makes
// Lanes3, Lanes4, RayFrame, TransferLut and SkipGrid (raycast.hpp) visible unqualified.
struct LaneKernels {
  // Blinn-Phong with a headlight (light and viewer along -dir), two-sided, white specular, over
  // lanes. An integer shininess (the default 10) is taken by repeated squaring, a few multiplies
  // where powf is a library call of about a hundred instructions.
  template <class L>
  static VOXWALL_HD_INLINE Lanes3<typename L::F> shadeLanes(const Lanes3<typename L::F>& color,
                                                            const Lanes3<typename L::F>& grad,
                                                            const Lanes3<typename L::F>& dir,
                                                            const RayFrame& f) {
    using F = typename L::F;
    const F len = L::sqrt(grad.x * grad.x + grad.y * grad.y + grad.z * grad.z);
    const F zero = L::splat(0.0f);
    const auto flat = L::butNot(zero == zero, len > L::splat(1e-12f));  // homogeneous: unshaded
    const F nl = L::abs(grad.x * dir.x + grad.y * dir.y + grad.z * dir.z) / len;
    F power;
    if (f.shininessInt < 0) {
      power = L::pow(nl, f.shininess);
    } else {
      power = L::splat(1.0f);
      F base = nl;
      for (int e = f.shininessInt; e; e >>= 1) {
        if (e & 1) power = power * base;
        base = base * base;
      }
    }
    const F spec = L::splat(f.specular) * power;
    const F kd = L::splat(f.ambient) + L::splat(f.diffuse) * nl;
    const F kFlat = L::splat(f.ambient + f.diffuse), one = L::splat(1.0f);
    auto channel = [&](F c) {
      const F lit = c * kd + spec;
      return L::select(flat, c * kFlat, L::select(one < lit, one, lit));
    };
    return {channel(color.x), channel(color.y), channel(color.z)};
  }

  // Unit world-space direction of the ray through the centre of pixel (px, py) of the virtual
  // screen. Tiles use the same global pixel coordinates, so a tile's rays are the full render's.
  template <class L>
  static VOXWALL_HD_INLINE Lanes3<typename L::F> pixelDirectionLanes(const RayFrame& f,
                                                                     typename L::I px,
                                                                     typename L::I py) {
    using F = typename L::F;
    const F one = L::splat(1.0f), half = L::splat(0.5f);
    const F sx = (L::toFloat(px) + half) / L::splat(float(f.screen.x)) * L::splat(2.0f) - one;
    const F sy = one - (L::toFloat(py) + half) / L::splat(float(f.screen.y)) * L::splat(2.0f);
    const Lanes3<F> dir{L::splat(f.forward.x) + sx * L::splat(f.right.x) + sy * L::splat(f.up.x),
                        L::splat(f.forward.y) + sx * L::splat(f.right.y) + sy * L::splat(f.up.y),
                        L::splat(f.forward.z) + sx * L::splat(f.right.z) + sy * L::splat(f.up.z)};
    const F invLen = one / L::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
    return {dir.x * invLen, dir.y * invLen, dir.z * invLen};
  }

  // Intersects o + t d with the box [lo, hi] in the lanes of m: returns the lanes that hit, with
  // their entry and exit in t0 and t1. d may have zeros (invD = 1 / d is then infinite).
  template <class L>
  static VOXWALL_HD_INLINE typename L::M rayBoxLanes(const glm::vec3& o,
                                                     const Lanes3<typename L::F>& d,
                                                     const Lanes3<typename L::F>& invD,
                                                     const glm::vec3& lo, const glm::vec3& hi,
                                                     typename L::M m, typename L::F& t0,
                                                     typename L::F& t1) {
    using F = typename L::F;
    const F zero = L::splat(0.0f);
    t0 = L::splat(-INFINITY), t1 = L::splat(INFINITY);
    auto slab = [&](float oa, F da, F inv, float la, float ha) {
      const auto flat = da == zero;
      if (oa < la || oa > ha) m = L::butNot(m, flat);  // parallel to the slab, outside it
      F tn = (L::splat(la) - L::splat(oa)) * inv, tf = (L::splat(ha) - L::splat(oa)) * inv;
      const auto swap = tn > tf;
      const F s = tn;
      tn = L::select(swap, tf, tn), tf = L::select(swap, s, tf);
      t0 = L::select(L::butNot(tn > t0, flat), tn, t0);
      t1 = L::select(L::butNot(tf < t1, flat), tf, t1);
    };
    slab(o.x, d.x, invD.x, lo.x, hi.x);
    slab(o.y, d.y, invD.y, lo.y, hi.y);
    slab(o.z, d.z, invD.z, lo.z, hi.z);
    return L::both(m, t0 <= t1);
  }

  // Front-to-back "over" of straight-colour samples with opacity alpha onto premultiplied acc.
  template <class L>
  static VOXWALL_HD_INLINE void compositeLanes(Lanes4<typename L::F>& acc,
                                               const Lanes3<typename L::F>& color,
                                               typename L::F alpha) {
    const typename L::F w = (L::splat(1.0f) - acc.a) * alpha;
    acc.r = acc.r + w * color.x;
    acc.g = acc.g + w * color.y;
    acc.b = acc.b + w * color.z;
    acc.a = acc.a + w;
  }

  // Values within this many table entries of each other make a segment short enough to take the
  // table at its back end (the integrals' difference would be mostly rounding).
  static constexpr float kNarrowSegment = 4.0f;

  // The colour and opacity of the ray segment whose value runs from `front` to `back`, from a
  // pre-integrated table (TransferLut says how); `point` is the table at `back` (depth in a).
  // The colour is the depth-weighted mean over the segment, the opacity 1 - exp(-depth): exact
  // for the opacity, and for the colour where it is constant over the segment (the emission
  // inside the segment is not attenuated by the segment itself). Values beyond the table's ends
  // count for its ends only where both ends of a segment are beyond the same end.
  template <class L>
  static VOXWALL_HD_INLINE Lanes4<typename L::F> segmentLanes(const TransferLut& lut,
                                                              typename L::F front,
                                                              typename L::F back,
                                                              const Lanes4<typename L::F>& point) {
    using F = typename L::F;
    const F zero = L::splat(0.0f), one = L::splat(1.0f), last = L::splat(lut.last);
    TransferLut table = lut;
    table.entries = lut.integral;
    const Lanes4<F> a = L::lookup(table, front), b = L::lookup(table, back);
    auto coordinate = [&](const F& v) {  // clamped as lookup() clamps, NaN kept as the scalar's
      const F x = (v - L::splat(lut.lo)) * L::splat(lut.scale);
      const F low = L::select(x < zero, zero, x);
      return L::select(last < low, last, low);
    };
    const F dx = coordinate(back) - coordinate(front);
    const auto wide = L::splat(kNarrowSegment) <= L::abs(dx);
    const F dG = b.a - a.a;
    const F depth = L::select(wide, dG / L::select(wide, dx, one), point.a);
    // Colour from the integrals where the segment holds some depth (else it composites ~nothing).
    const auto mixed = L::both(wide, L::splat(1e-6f) < L::abs(dG));
    const F inv = one / L::select(mixed, dG, one);
    auto channel = [&](const F& ka, const F& kb, const F& p) {
      const F c = (kb - ka) * inv;
      return L::select(mixed, L::select(c < zero, zero, L::select(one < c, one, c)), p);
    };
    return {channel(a.r, b.r, point.r), channel(a.g, b.g, point.g), channel(a.b, b.b, point.b),
            one - L::exp(zero - depth)};
  }

  // Traces the rays through pixels (px, py) of the virtual screen, one per lane of L (valid: the
  // lanes that hold a pixel), into premultiplied colour and opacity and the samples taken.
  // `View` meets the view contract (VolumeView in view_concept.hpp: sample(x, y, z, RayCache&) is
  // the trilinear sample in index space, the cache per-ray state the view may use to reuse work
  // between consecutive samples, sampleNear the gradient's neighbours); its values are looked up
  // in `lut`. Samples sit at t = tEnter + (k + 1/2) * stepWorld. With a skip grid each ray walks
  // coarse cells: a cell's emptiness is looked up once per crossing and an empty cell is jumped
  // over; inside a non-empty cell, a sample whose fine cell is empty is skipped (checked only after
  // a transparent sample). A skipped sample would have had opacity exactly zero, and positions
  // are computed from k, never accumulated, so the image is the same with and without skipping.
  // With a pre-integrated table (lut.integral) sample k composites the segment from sample k - 1
  // (whose value is sampled again where it was skipped) to sample k, and a sample is skipped only
  // when the previous one also lies in an empty cell: the transfer function is zero over both
  // cells' value ranges, which overlap (each is grown by a voxel and the cells touch, the step
  // being shorter than a cell), so the segment between them would have composited nothing.
  // Every lane keeps its own k, cell and cache; a lane drops out when its ray terminates or leaves
  // the volume, and the packet ends when all have.
  template <class L, codec::kernels::VolumeView View>
  static VOXWALL_HD_INLINE void raycastLanes(const View& view, const RayFrame& f,
                                             const TransferLut& lut, const SkipGrid& skip,
                                             typename L::I px, typename L::I py,
                                             typename L::M valid, Lanes4<typename L::F>& acc,
                                             typename L::I& samples) {
    using F = typename L::F;
    using I = typename L::I;
    using M = typename L::M;
    const F zero = L::splat(0.0f), one = L::splat(1.0f), half = L::splat(0.5f);
    acc = {zero, zero, zero, zero};
    samples = L::splatI(0);
    const Lanes3<F> dir = pixelDirectionLanes<L>(f, px, py);
    // Index space: the eye is the same for every ray.
    const glm::vec3 o = f.eyeWorld * f.invSpacing + f.centerIndex;
    const Lanes3<F> d{dir.x * L::splat(f.invSpacing.x), dir.y * L::splat(f.invSpacing.y),
                      dir.z * L::splat(f.invSpacing.z)};
    const Lanes3<F> invD{one / d.x, one / d.y, one / d.z};
    // Entry and exit of the box [-0.5, dims - 0.5].
    F t0, t1;
    M hit = rayBoxLanes<L>(o, d, invD, glm::vec3(-0.5f), f.boxMax, valid, t0, t1);
    const F tEnter = L::select(hit, L::select(t0 > zero, t0, zero), zero);
    const F tExit = L::select(hit, t1, zero);
    hit = L::both(hit, tExit > tEnter);
    if (!L::any(hit)) return;
    // Samples at (k + 1/2) steps that lie inside [tEnter, tExit); robust to rounding at the exit.
    const I steps =
        L::selectI(hit, L::ceilInt((tExit - tEnter) / L::splat(f.stepWorld) - half), L::splatI(0));
    const float invStep = 1.0f / f.stepWorld;
    const F step = L::splat(f.stepWorld);
    const I oneI = L::splatI(1), zeroI = L::splatI(0);
    typename L::template Caches<View> cache;  // the view's per-ray state (e.g. the last cell)
    // Views that traverse a mip hierarchy (svmm, ksvd) take the sampling mode and the ray's
    // footprint, and may report the region around a sample where every sample has its value (an
    // svmm terminal block): a transparent one is skipped in one step.
    constexpr bool traversal = requires { View::kTraversal; };
    static_assert(!traversal || codec::kernels::TraversalView<View>,
                  "a view that declares kTraversal must meet TraversalView: its RayCache needs "
                  "footprint, nearest, regionValid, regionLo/Hi and regionFootprintMax");
    if constexpr (traversal) L::template setNearest<View>(cache, f.nearest);
    I k = zeroI, kEnd = zeroI;  // the next sample and the end of its coarse cell
    M live = L::both(hit, L::lessI(zeroI, steps));
    M transparent = hit;  // was the ray's last sample fully transparent?
    const M none = zero != zero;
    // Pre-integration: the value of sample k - 1 where it was taken (havePrev), whether sample
    // k - 1 lies in an empty cell (sample 0 has no segment before it), and the lanes that take
    // the first sample of an empty coarse cell (the segment into it) and then jump it.
    const bool pre = lut.integral != nullptr;
    F prev = zero;
    M havePrev = none, prevEmpty = hit, jumpAfter = none;
    auto position = [&](const F& t) {
      return Lanes3<F>{L::splat(o.x) + t * d.x, L::splat(o.y) + t * d.y, L::splat(o.z) + t * d.z};
    };
    // The voxel index of a position, 0 for the volume's outer half voxel below 0.
    auto voxelIndex = [&](const F& v) { return L::selectI(v < zero, zeroI, L::trunc(v)); };
    while (L::any(live)) {
      if (skip.empty) {
        // Lanes past their coarse cell look up the next one, and jump it while it is empty.
        M need = L::butNot(live, L::lessI(k, kEnd));
        while (L::any(need)) {
          const Lanes3<F> p = position(tEnter + (L::toFloat(k) + half) * step);
          // The cell of the sample's lower trilinear corner: its range covers every voxel it reads.
          const I cx = L::shiftRight(voxelIndex(p.x), skip.cellShift);
          const I cy = L::shiftRight(voxelIndex(p.y), skip.cellShift);
          const I cz = L::shiftRight(voxelIndex(p.z), skip.cellShift);
          const F size = L::splat(float(1 << skip.cellShift)), below = L::splat(-1.0f);
          // Cell 0 also holds positions in [-0.5, 0): extend its lower bound. Then the ray
          // parameter where it leaves the cell (boxExit).
          F tCell = L::splat(INFINITY);
          auto exitAlong = [&](const I& c, const F& inv, float oa) {
            const F lo = L::select(L::isZeroI(c), below, L::toFloat(c) * size);
            const F hi = L::toFloat(c + oneI) * size;
            const F ta = (L::select(inv > zero, hi, lo) - L::splat(oa)) * inv;
            tCell = L::select(ta < tCell, ta, tCell);
          };
          exitAlong(cx, invD.x, o.x);
          exitAlong(cy, invD.y, o.y);
          exitAlong(cz, invD.z, o.z);
          // First sample index at or past the cell's exit; at least the next one.
          const F kCell = (tCell - tEnter) * L::splat(invStep) - half;
          I next = L::selectI(kCell >= L::toFloat(steps), steps,
                              L::ceilInt(L::select(kCell >= L::toFloat(steps), zero, kCell)));
          next = L::selectI(L::lessI(k + oneI, next), next, k + oneI);
          kEnd = L::selectI(need, next, kEnd);
          const M inside = L::both(
              L::both(L::lessI(cx, L::splatI(skip.cellsX)), L::lessI(cy, L::splatI(skip.cellsY))),
              L::lessI(cz, L::splatI(skip.cellsZ)));
          const I cell = (cz * L::splatI(skip.cellsY) + cy) * L::splatI(skip.cellsX) + cx;
          const M empty = L::byteSet(skip.empty, cell, L::both(need, inside));
          const M jump = pre ? L::both(empty, prevEmpty) : empty;
          if (pre) {
            jumpAfter = L::either(jumpAfter, L::butNot(empty, jump));
            havePrev = L::butNot(havePrev, jump);  // sample kEnd - 1 (in the cell) was not taken
          }
          k = L::selectI(jump, kEnd, k);
          live = L::both(live, L::lessI(k, steps));
          need = L::both(jump, live);
        }
        if (!L::any(live)) break;
      }
      const F t = tEnter + (L::toFloat(k) + half) * step;
      const Lanes3<F> p = position(t);
      M go = live;
      M skipped = none, inEmpty = jumpAfter;  // inEmpty: sample k lies in an empty cell
      // Fine cells are checked only after a transparent sample: inside opaque material they
      // would almost never skip, and the check costs as much as a tenth of a sample.
      if (skip.fineEmpty) {
        const M check = L::both(go, transparent);
        if (L::any(check)) {
          auto fine = [&](const F& v, int cells) {
            const I c = L::shiftRight(voxelIndex(v), skip.fineShift), last = L::splatI(cells - 1);
            return L::selectI(L::lessI(c, last), c, last);
          };
          const I fx = fine(p.x, skip.fineX), fy = fine(p.y, skip.fineY),
                  fz = fine(p.z, skip.fineZ);
          const I cell = (fz * L::splatI(skip.fineY) + fy) * L::splatI(skip.fineX) + fx;
          inEmpty = L::either(inEmpty, L::bitSet(skip.fineEmpty, cell, check));
          skipped = pre ? L::both(inEmpty, prevEmpty) : inEmpty;
          go = L::butNot(go, skipped);
        }
      }
      if (L::any(go)) {
        samples = samples + L::selectI(go, oneI, zeroI);
        if constexpr (traversal) {
          if (f.lodAngle > 0.0f)
            L::template setFootprint<View>(cache, t * L::splat(f.lodAngle), go);
        }
        // The segment's front value first: the view's cache ends on sample k, as the traversal
        // below needs.
        F front = prev;
        const M needFront = L::butNot(L::both(go, L::lessI(zeroI, k)), havePrev);
        if (pre && L::any(needFront)) {
          const F tFront = tEnter + (L::toFloat(k - oneI) + half) * step;
          if constexpr (traversal) {
            if (f.lodAngle > 0.0f)
              L::template setFootprint<View>(cache, tFront * L::splat(f.lodAngle), needFront);
          }
          front = L::select(needFront, L::sample(view, cache, position(tFront), needFront), prev);
          samples = samples + L::selectI(needFront, oneI, zeroI);
          if constexpr (traversal) {
            if (f.lodAngle > 0.0f)
              L::template setFootprint<View>(cache, t * L::splat(f.lodAngle), go);
          }
        }
        const F value = L::sample(view, cache, p, go);
        Lanes4<F> c = L::lookup(lut, value);
        transparent = L::selectM(go, c.a <= zero, transparent);
        if (pre) {
          // Sample 0 has no segment before it: its own value at both ends.
          c = segmentLanes<L>(lut, L::select(L::either(havePrev, needFront), front, value), value,
                              c);
          prev = L::select(go, value, prev);
          havePrev = L::either(havePrev, go);
        }
        Lanes3<F> color{c.r, c.g, c.b};
        // A transparent sample composites nothing; only the (costly) shading branches on it.
        if (f.shading) {
          const M lit = L::both(go, c.a > zero);
          if (L::any(lit)) {
            // A segment is lit at its middle, where the view is sampled again (the gradient
            // follows the sample); the first sample of a ray, which has no segment, at itself.
            Lanes3<F> at = p;
            const M middle = pre ? L::both(lit, L::lessI(zeroI, k)) : none;
            if (L::any(middle)) {
              at = position(L::select(middle, t - half * step, t));
              (void)L::sample(view, cache, at, middle);
            }
            const Lanes3<F> shaded =
                shadeLanes<L>(color, L::template gradient<View>(view, cache, f, at, lit), dir, f);
            color = {L::select(lit, shaded.x, color.x), L::select(lit, shaded.y, color.y),
                     L::select(lit, shaded.z, color.z)};
            // The traversal below reads the region of sample k: sample it again where needed.
            if constexpr (traversal) {
              const M again = L::both(middle, transparent);
              if (L::any(again)) (void)L::sample(view, cache, p, again);
            }
          }
        }
        compositeLanes<L>(acc, color, L::select(go, c.a, zero));  // lanes not sampling add nothing
        const M done = L::both(go, acc.a >= L::splat(f.earlyTermination));
        live = L::butNot(live, done);
        if constexpr (traversal) {
          const M region = L::butNot(L::both(go, transparent), done);
          if (L::any(region)) {
            // Every sample up to `next` has sample k's value: `prev` stays right for `next`.
            const I next =
                L::template regionEnd<View>(cache, o, invD, f, tEnter, invStep, steps, k, region);
            inEmpty = L::butNot(inEmpty, L::both(region, L::lessI(k + oneI, next)));
            k = L::selectI(region, next - oneI, k);
          }
        }
      }
      if (pre) {
        // Lanes that took the first sample of an empty coarse cell jump the rest of it.
        const M jumpNow = L::both(jumpAfter, L::both(go, L::lessI(k, kEnd - oneI)));
        k = L::selectI(jumpNow, kEnd - oneI, k);
        havePrev = L::butNot(havePrev, L::either(skipped, jumpNow));
        jumpAfter = L::butNot(jumpAfter, go);
        prevEmpty = L::selectM(L::either(go, skipped), inEmpty, prevEmpty);
      }
      k = k + L::selectI(L::either(go, skipped), oneI, zeroI);
      live = L::both(live, L::lessI(k, steps));
    }
  }
};
