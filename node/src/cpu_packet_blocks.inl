// The CPU backend's packet loop over a tile's blocks: packets of kW x kH neighbouring rays over
// each block, or, for a ray lattice's refinement (TileJob::need), the wanted points of the block
// packed into full packets. Included by cpu_view_targets.hpp once per SIMD target, inside
// Highway's target region and after HwyLanes and LaneKernels (so that this code is compiled for
// that target's instruction set, as raycast_lanes.inl says why). No include guard, by design.

// The points of block [x0, x1) x [y0, y1) that a lattice's refinement wants (TileJob::need), in
// the order of the kW x kH groups they lie in, so that neighbouring lanes stay neighbours, into
// px and py, followed by `pad` points (0, 0) for the lanes past the end; returns how many.
template <int kW, int kH, int pad>
int wantedPoints(const TileJob& job, int x0, int y0, int x1, int y1, std::int32_t* px,
                 std::int32_t* py) {
  int count = 0;
  for (int gy = y0; gy < y1; gy += kH)
    for (int gx = x0; gx < x1; gx += kW)
      for (int i = 0; i < kW * kH; ++i) {
        const int x = gx + i % kW, y = gy + i / kW;
        if (x < x1 && y < y1 &&
            job.need[std::size_t(y) * std::size_t(job.tile.width) + std::size_t(x)])
          px[count] = x, py[count] = y, ++count;
      }
  std::fill(px + count, px + count + pad, 0);
  std::fill(py + count, py + count + pad, 0);
  return count;
}

// Packets of kW x kH rays over each block.
template <class View>
std::uint64_t renderPacketBlocks(const View& view, const TileJob& job) {
  using L = HwyLanes;
  constexpr int kW = L::kLanes >= 8 ? 4 : 2, kH = int(L::kLanes) / kW;
  static_assert(kBlockPixels % kW == 0 && kBlockPixels % kH == 0);
  const auto lut = job.plan.lut.view();
  const L::DI di;
  const auto lane = hn::Iota(di, 0);
  constexpr int kRowShift = kW == 4 ? 2 : 1;  // lane / kW
  const auto laneX = hn::And(lane, hn::Set(di, kW - 1)), laneY = hn::ShiftRight<kRowShift>(lane);
  return forEachBlock(job, [&](int x0, int y0, int x1, int y1, std::uint64_t& samples) {
    // This thread's hold on the pages while it renders the block (page_cache.hpp).
    std::optional<PageCache::Reader> reader, coarse;
    if constexpr (kPaged<View>)
      if (job.pages) reader.emplace(*job.pages);
    if constexpr (kLevels<View>)
      if (job.coarsePages) coarse.emplace(*job.coarsePages);
    const ReaderScope scope(reader ? &*reader : nullptr, coarse ? &*coarse : nullptr);
    HWY_ALIGN float r[L::kLanes], g[L::kLanes], b[L::kLanes], a[L::kLanes];
    HWY_ALIGN std::int32_t n[L::kLanes];
    const auto stride = hn::Set(di, job.stride);
    // Traces the points (lx, ly) of the lanes of `valid`; lane i's pixel goes to pointOf(i).
    auto trace = [&](L::I lx, L::I ly, L::M valid, const auto& pointOf) {
      kernels::Lanes4<L::F> acc;
      L::I count;
      LaneKernels::raycastLanes<L>(view, job.plan.ray, lut, job.plan.skip,
                                   lx * stride + hn::Set(di, job.tile.x),
                                   ly * stride + hn::Set(di, job.tile.y), valid, acc, count);
      hn::Store(acc.r, L::D(), r), hn::Store(acc.g, L::D(), g);
      hn::Store(acc.b, L::D(), b), hn::Store(acc.a, L::D(), a), hn::Store(count, di, n);
      L::forLanes(valid, [&](std::size_t i) {
        const auto [x, y] = pointOf(int(i));
        job.out.at(x, y) = kernels::packRgba8(glm::vec4(r[i], g[i], b[i], a[i]));
        samples += std::uint64_t(n[i]);
      });
    };
    if (job.need) {
      // Only some points are wanted (a lattice's refinement): they are packed into full packets,
      // in the order of the kW x kH groups they lie in, so neighbouring lanes stay neighbours.
      constexpr int kMost = kBlockPixels * kBlockPixels + int(L::kLanes);  // a packet's tail too
      HWY_ALIGN std::int32_t px[kMost], py[kMost];
      const int count = wantedPoints<kW, kH, int(L::kLanes)>(job, x0, y0, x1, y1, px, py);
      for (int first = 0; first < count; first += int(L::kLanes)) {
        const int left = count - first;
        const auto lx = hn::Load(di, px + first), ly = hn::Load(di, py + first);
        trace(lx, ly, L::lessI(lane, hn::Set(di, left)), [&](int i) {
          return std::pair{px[first + i], py[first + i]};
        });
      }
      return;
    }
    for (int y = y0; y < y1; y += kH)
      for (int x = x0; x < x1; x += kW) {
        const auto lx = laneX + hn::Set(di, x), ly = laneY + hn::Set(di, y);
        trace(lx, ly, L::both(L::lessI(lx, hn::Set(di, x1)), L::lessI(ly, hn::Set(di, y1))),
              [&](int i) {
                return std::pair{x + i % kW, y + i / kW};
              });
      }
  });
}
