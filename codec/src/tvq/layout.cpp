// The tvq codec's layout: every section checked against the header before anything reads it, the
// view the raycaster samples, and the decoder. The byte layout is documented in tvq_codec.hpp.
#include <sys/mman.h>
#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <new>
#include <voxwall/codec/brick_volume.hpp>
#include <voxwall/codec/host_tables.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/core/bytes.hpp>
#include <voxwall/core/errors.hpp>

#include "format.hpp"

namespace voxwall::codec::tvq {

namespace {
// What the associated codebooks are made from (the transform, the basis, the sub-volumes' scales
// and chapters, the codebooks): two ranks with the same key make the same bytes. Never 0.
std::uint64_t booksKey(const SectionSet& sections) {
  std::uint64_t h = 0x766f7877616c6cull;
  for (std::uint32_t id : {kParams, kBasis, kSubvolumes, kCodebooks}) {
    const auto bytes = sections.get(id, "section");  // the constructor checked each is there
    h = XXH64(bytes.data(), bytes.size(), h);
  }
  return h ? h : 1;
}
}  // namespace

Layout::Layout(const VolumeInfo& info, const SectionSet& sections) : info_(info) {
  cacheId_ = mintCacheIds(kProgressiveLevels);  // one id per progressive level
  const std::uint64_t subCount = readParams(sections);
  readBasis(sections);
  const auto [words, recordBytes] = readSubvolumes(sections, subCount);
  buildTable(sections, words, recordBytes);
  books_ = std::make_unique<Books>(*this, booksKey(sections));
}

Layout::~Layout() = default;

std::uint64_t Layout::readParams(const SectionSet& sections) {
  const std::string& src = sections.source;
  ByteReader r(sections.get(kParams, "params"), src, "section 'params'");
  if (r.remaining() != kParamsBytes)
    r.fail(std::to_string(r.remaining()) + " bytes, expected " + std::to_string(kParamsBytes));
  const std::uint32_t transform = r.get<std::uint32_t>();
  const std::uint32_t s = r.get<std::uint32_t>();
  const std::uint32_t dcBits = r.get<std::uint32_t>();
  const std::uint32_t classified = r.get<std::uint32_t>();
  const std::uint32_t codeBits = r.get<std::uint32_t>();
  const std::uint32_t reserved = r.get<std::uint32_t>();
  fidelity_ = r.get<double>(), dcLo_ = r.get<double>(), dcStep_ = r.get<double>();
  for (double& v : levelPsnr_) v = r.get<double>();
  const std::uint64_t subCount = r.get<std::uint64_t>();
  if (transform != 1 && transform != 2)
    r.fail("transform " + std::to_string(transform) + " (1 KLT, 2 DCT)");
  if (s < 1 || s > std::uint32_t(kMaxSubvolumeBlocks))
    r.fail("sub-volume side " + std::to_string(s) + " blocks (1.." +
           std::to_string(kMaxSubvolumeBlocks) + ")");
  if (dcBits < 1 || dcBits > 16) r.fail("mean bits " + std::to_string(dcBits) + " (1..16)");
  if (classified > 1) r.fail("classified flag " + std::to_string(classified));
  if (codeBits > std::uint32_t(kMaxCodeBitsTotal)) r.fail("code bits " + std::to_string(codeBits));
  if (reserved != 0) r.fail("reserved field is not zero");
  if (!(fidelity_ >= 0 && fidelity_ < 1)) r.fail("fidelity out of range");
  if (!std::isfinite(dcLo_) || std::abs(dcLo_) > 1e30) r.fail("mean offset is not a finite number");
  if (!(dcStep_ > 0) || !(dcStep_ * 65536.0 < 1e30)) r.fail("mean step out of range");
  for (double v : levelPsnr_)
    if (std::isnan(v)) r.fail("a PSNR is not a number");
  transform_ = Transform(transform), s_ = int(s), dcBits_ = int(dcBits);
  classified_ = classified == 1, codeBits_ = int(codeBits);
  const Grid grid(info_.dims, s_);
  blocks_ = grid.blocks, grid_ = grid.subs;
  if (subCount != grid.subCount())
    r.fail(std::to_string(subCount) + " sub-volumes, the grid has " +
           std::to_string(grid.subCount()));
  return subCount;
}

void Layout::readBasis(const SectionSet& sections) {
  const std::string& src = sections.source;
  ByteReader br(sections.get(kBasis, "basis"), src, "section 'basis'");
  if (br.remaining() != 64 * 64 * 4 + 64)
    br.fail(std::to_string(br.remaining()) + " bytes, expected " +
            std::to_string(64 * 64 * 4 + 64));
  for (float& v : basis_.rows) {
    v = br.get<float>();
    if (!(std::abs(v) <= 1.0f)) br.fail("a basis value outside [-1, 1]");
  }
  std::array<int, 8> zoneSize{};
  for (std::uint8_t& z : basis_.zone) {
    z = br.get<std::uint8_t>();
    if (z > 7) br.fail("zone " + std::to_string(z) + " (0..7)");
    ++zoneSize[z];
  }
  if (basis_.zone[0] != 0) br.fail("coefficient 0 (the mean) is not in zone 0");
  for (int z = 0; z < 8; ++z)
    if (zoneSize[std::size_t(z)] != 8)
      br.fail("zone " + std::to_string(z) + " holds " + std::to_string(zoneSize[std::size_t(z)]) +
              " coefficients, not 8");
}

std::pair<std::uint64_t, std::uint64_t> Layout::readSubvolumes(const SectionSet& sections,
                                                               std::uint64_t subCount) {
  const std::string& src = sections.source;
  const Grid grid(info_.dims, s_);
  std::array<std::vector<int>, 3> chapterDims;
  for (int p = 0; p < 3; ++p)
    for (int c = 0; c < chapterCount(p); ++c)
      chapterDims[std::size_t(p)].push_back(
          int(chapterCoefficients(basis_, p, firstChapterClass(p) + c).size()));
  ByteReader sr(sections.get(kSubvolumes, "sub-volumes"), src, "section 'sub-volumes'");
  if (sr.remaining() != subCount * kSubvolumeBytes)
    sr.fail(std::to_string(sr.remaining()) + " bytes for " + std::to_string(subCount) +
            " sub-volumes of " + std::to_string(kSubvolumeBytes));
  std::uint64_t bookValues = 0, words = 0, recordBytes = 0;
  for (std::uint64_t i = 0; i < subCount; ++i) {
    Sub sub;
    const std::string which = "sub-volume " + std::to_string(i);
    for (int& b : sub.bits) {
      b = sr.get<std::uint8_t>();
      if (b > kMaxCodeBits)
        sr.fail(which + ": " + std::to_string(b) + " code bits (0.." +
                std::to_string(kMaxCodeBits) + ")");
    }
    if (sr.get<std::uint8_t>() != 0) sr.fail(which + ": reserved byte is not zero");
    sub.background = sr.get<std::uint32_t>();
    if (sub.background >> dcBits_) sr.fail(which + ": background mean does not fit the mean bits");
    sub.coded = sr.get<std::uint64_t>();
    const std::uint64_t local = Grid::volume(grid.extent(i));
    if (sub.coded > local)
      sr.fail(which + ": " + std::to_string(sub.coded) + " coded blocks of " +
              std::to_string(local));
    for (float& v : sub.scale) {
      v = sr.get<float>();
      if (!(v >= 0 && v <= kMaxScale)) sr.fail(which + ": a codebook scale out of range");
    }
    for (int p = 0; p < 3; ++p) {
      std::uint64_t total = 1;
      sub.codebookAt[std::size_t(p)] = bookValues;
      for (int c = 0; c < chapterCount(p); ++c) {
        const std::uint32_t n = sr.get<std::uint32_t>();
        sub.chapters[std::size_t(p)].push_back(n);
        total += n;
        bookValues += std::uint64_t(n) * std::uint64_t(chapterDims[std::size_t(p)][std::size_t(c)]);
        if (total > (std::uint64_t(1) << sub.bits[std::size_t(p)]))
          sr.fail(which + ": partition " + std::to_string(p) +
                  "'s chapters hold more codevectors than its " +
                  std::to_string(sub.bits[std::size_t(p)]) + " code bits address");
      }
      codevectors_[std::size_t(p)] += total - 1;
    }
    sub.firstWord = words, sub.firstRecordByte = recordBytes;
    words += (local + 63) / 64;
    recordBytes +=
        (sub.coded * std::uint64_t(dcBits_ + sub.bits[0] + sub.bits[1] + sub.bits[2]) + 7) / 8;
    coded_ += sub.coded;
    subvolumes_.push_back(std::move(sub));
  }
  codebooks_ = sections.get(kCodebooks, "codebooks");
  if (codebooks_.size() != bookValues * 2)
    ByteReader(codebooks_, src, "section 'codebooks'")
        .fail(std::to_string(codebooks_.size()) + " bytes, the chapters need " +
              std::to_string(bookValues * 2));
  return {words, recordBytes};
}

// Sub-volumes' associated codebooks, each made the first time a block of it is decoded (any
// render thread; the others wait for it) and kept until clear() or the object goes.
// Every sub-volume's codebooks have their place (codebookAt) in one region: a slot of the file
// the ranks on this host share (host_tables.hpp) where this process has one, so that one rank
// makes a sub-volume's codebooks and the others read them; otherwise anonymous memory of this
// process, reserved untouched when the first is made. Either way making them touches only their
// pages, and clear() gives every page back to the system at once (MADV_DONTNEED; the shared slot's
// when the last process detaches), with no allocator in between to keep freed memory resident.
class Layout::Books {
 public:
  // `key` names the codebooks for the ranks on the host (what they are made from); 0: never
  // shared (a decode's scratch codebooks).
  explicit Books(const Layout& layout, std::uint64_t key = 0)
      : layout_(layout),
        slots_(layout.table_.size()),
        bytes_(std::max<std::uint64_t>(layout.booksBytes_, 1)),
        key_(key) {}
  ~Books() {
    if (region_) munmap(region_, bytes_);
  }
  Books(const Books&) = delete;
  Books& operator=(const Books&) = delete;

  static const std::uint8_t* fetch(const void* owner, std::uint64_t s) {
    return static_cast<const Books*>(owner)->get(s);
  }
  const std::uint8_t* get(std::uint64_t s) const {
    if (auto* p = slots_[s].load(std::memory_order_acquire)) return p;
    std::lock_guard lock(locks_[s % locks_.size()]);
    if (auto* p = slots_[s].load(std::memory_order_relaxed)) return p;
    const std::uint64_t at = layout_.table_[s].codebookAt[0];
    std::uint8_t* p = nullptr;
    if (const hosttables::Region* shared = sharedRegion()) {
      p = shared->data() + at;  // zeros until made, here or by another rank
      shared->makeOnce(s, [&] { layout_.associateCodebooks(s, reinterpret_cast<float*>(p)); });
    } else {
      std::call_once(mapOnce_, [this] {
        void* r = mmap(nullptr, bytes_, PROT_READ | PROT_WRITE,
                       MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
        if (r == MAP_FAILED) throw std::bad_alloc();  // call_once tries again next time
        region_ = static_cast<std::uint8_t*>(r);
      });
      p = region_ + at;  // zeros: never written, or cleared
      layout_.associateCodebooks(s, reinterpret_cast<float*>(p));
    }
    resident_.fetch_add(layout_.subBooksBytes(s), std::memory_order_relaxed);
    slots_[s].store(p, std::memory_order_release);
    return p;
  }
  std::uint64_t resident() const { return resident_.load(std::memory_order_relaxed); }
  // Not while get() may run: a decode holds a slot's pointer.
  void clear() const {
    for (auto& slot : slots_) slot.store(nullptr, std::memory_order_relaxed);
    if (region_) madvise(region_, bytes_, MADV_DONTNEED);  // reads back as zeros
    shared_.reset(), sharedTried_ = false;
    resident_.store(0, std::memory_order_relaxed);
  }

 private:
  // The shared slot, attached at the first get() after construction or clear(), where this
  // process has a shared file; a whole epoch is either shared or private.
  const hosttables::Region* sharedRegion() const {
    if (key_ == 0) return nullptr;
    std::lock_guard lock(sharedLock_);
    if (!sharedTried_) {
      shared_ = hosttables::Region::attach(key_, layout_.table_.size(), bytes_);
      sharedTried_ = true;
    }
    return shared_.get();
  }
  const Layout& layout_;
  mutable std::vector<std::atomic<std::uint8_t*>> slots_;
  mutable std::array<std::mutex, 64> locks_;
  mutable std::atomic<std::uint64_t> resident_{0};
  std::uint64_t bytes_;
  mutable std::once_flag mapOnce_;
  mutable std::uint8_t* region_ = nullptr;
  std::uint64_t key_;
  mutable std::mutex sharedLock_;
  mutable std::unique_ptr<hosttables::Region> shared_;
  mutable bool sharedTried_ = false;
};

void Layout::buildTable(const SectionSet& sections, std::uint64_t words,
                        std::uint64_t recordBytes) {
  const std::string& src = sections.source;
  const std::uint64_t subCount = subvolumes_.size();
  const Grid grid(info_.dims, s_);
  occupancy_ = sections.get(kOccupancy, "occupancy");
  ByteReader orr(occupancy_, src, "section 'occupancy'");
  if (occupancy_.size() != words * 8)
    orr.fail(std::to_string(occupancy_.size()) + " bytes, the sub-volumes need " +
             std::to_string(words * 8));
  records_ = sections.get(kRecords, "records");
  ByteReader rr(records_, src, "section 'records'");
  if (records_.size() != recordBytes)
    rr.fail(std::to_string(records_.size()) + " bytes, the coded blocks need " +
            std::to_string(recordBytes));
  table_.assign(subCount, kernels::TvqSubvolume{});
  ranks_.assign(words, 0);
  std::uint64_t at = 0;  // in the associated codebooks of every sub-volume, one after the other
  for (std::uint64_t i = 0; i < subCount; ++i) {
    const Sub& sub = subvolumes_[i];
    kernels::TvqSubvolume& t = table_[i];
    for (int p = 0; p < 3; ++p) {
      std::uint64_t n = 1;  // the zero vector first
      for (std::uint32_t c : sub.chapters[std::size_t(p)]) n += c;
      t.codebookAt[p] = at;
      at += n * kBlockVoxels * sizeof(float);
    }
    const glm::ivec3 first = grid.first(i), extent = grid.extent(i);
    for (int a = 0; a < 3; ++a) t.firstBlock[a] = first[a], t.blocks[a] = extent[a];
    for (int p = 0; p < 3; ++p) t.codeBits[p] = sub.bits[std::size_t(p)];
    t.recordBits = dcBits_ + sub.bits[0] + sub.bits[1] + sub.bits[2];
    t.background = float(dcLo_ + double(sub.background) * dcStep_);
    t.occupancyAt = sub.firstWord * 8;
    t.rankAt = sub.firstWord * 4;
    t.recordsAt = sub.firstRecordByte;
    rankOccupancy(i, Grid::volume(extent), orr);
    checkRecords(i, rr);
  }
  booksBytes_ = at;
}

std::uint64_t Layout::subBooksBytes(std::uint64_t s) const {
  return (s + 1 < table_.size() ? table_[s + 1].codebookAt[0] : booksBytes_) -
         table_[s].codebookAt[0];
}

// The rank of every occupancy word of sub-volume i (coded blocks before it), checking the words
// against the sub-volume's size and coded count.
void Layout::rankOccupancy(std::uint64_t i, std::uint64_t local, const ByteReader& orr) {
  const kernels::TvqSubvolume& t = table_[i];
  const auto* w = reinterpret_cast<const std::uint64_t*>(occupancy_.data() + t.occupancyAt);
  std::uint32_t* rank = ranks_.data() + t.rankAt / 4;
  std::uint64_t seen = 0;
  for (std::uint64_t j = 0; j < (local + 63) / 64; ++j) {
    rank[j] = std::uint32_t(seen);
    std::uint64_t word = w[j];
    if (j == (local - 1) / 64 && local % 64 && (word >> (local % 64)))
      orr.fail("sub-volume " + std::to_string(i) + ": bits set past its blocks");
    seen += std::uint64_t(std::popcount(word));
  }
  if (seen != subvolumes_[i].coded)
    orr.fail("sub-volume " + std::to_string(i) + ": " + std::to_string(seen) +
             " coded blocks, the table says " + std::to_string(subvolumes_[i].coded));
}

// Every record's codes name a codevector of its partition.
void Layout::checkRecords(std::uint64_t i, const ByteReader& rr) const {
  kernels::TvqDecoder d;
  d.records = reinterpret_cast<const std::uint8_t*>(records_.data());
  d.dcBits = dcBits_;
  std::array<std::uint64_t, 3> limit{};
  for (int p = 0; p < 3; ++p) {
    limit[std::size_t(p)] = 1;
    for (std::uint32_t c : subvolumes_[i].chapters[std::size_t(p)]) limit[std::size_t(p)] += c;
  }
  for (std::uint64_t j = 0; j < subvolumes_[i].coded; ++j) {
    std::uint32_t dc, k[3];
    d.codes(table_[i], j, dc, k);
    for (int p = 0; p < 3; ++p)
      if (k[p] >= limit[std::size_t(p)])
        rr.fail("sub-volume " + std::to_string(i) + ", record " + std::to_string(j) + ": code " +
                std::to_string(k[p]) + " of partition " + std::to_string(p) + " has " +
                std::to_string(limit[std::size_t(p)]) + " codevectors");
  }
}

// Each codevector of sub-volume s taken back through the inverse transform (section 4.3,
// equation 5), so that decoding never does; `out` holds its partitions from codebookAt[0] on.
void Layout::associateCodebooks(std::uint64_t s, float* out) const {
  const Sub& sub = subvolumes_[s];
  const kernels::TvqSubvolume& t = table_[s];
  const std::int16_t* book = reinterpret_cast<const std::int16_t*>(codebooks_.data());
  for (int p = 0; p < 3; ++p) {
    float* o = out + (t.codebookAt[p] - t.codebookAt[0]) / sizeof(float) + kBlockVoxels;
    std::uint64_t value = sub.codebookAt[std::size_t(p)];
    for (int c = 0; c < chapterCount(p); ++c) {
      const auto ks = chapterCoefficients(basis_, p, firstChapterClass(p) + c);
      for (std::uint32_t v = 0; v < sub.chapters[std::size_t(p)][std::size_t(c)]; ++v) {
        for (int k : ks) {
          std::int16_t q;
          std::memcpy(&q, book + value++, 2);
          const float coef = float(q) * sub.scale[std::size_t(p)];
          const float* row = basis_.row(k);
          for (int j = 0; j < kBlockVoxels; ++j) o[j] += coef * row[j];
        }
        o += kBlockVoxels;
      }
    }
  }
}

std::uint64_t Layout::associatedResidentBytes() const { return books_->resident(); }

void Layout::releaseAssociated() const { books_->clear(); }

namespace {
// Where each part lies in the joined buffer: the table, the codebooks, the ranks, the occupancy
// words, the records (and 8 bytes more).
struct Joined {
  std::uint64_t books, ranks, occupancy, records, end;
};
Joined joinedLayout(std::uint64_t subCount, std::uint64_t books, std::uint64_t words,
                    std::uint64_t records) {
  auto align8 = [](std::uint64_t v) { return (v + 7) / 8 * 8; };
  Joined j;
  j.books = subCount * sizeof(kernels::TvqSubvolume);
  j.ranks = align8(j.books + books);
  j.occupancy = align8(j.ranks + words * 4);
  j.records = j.occupancy + words * 8;
  j.end = j.records + records + 8;
  return j;
}
}  // namespace

std::vector<std::byte> Layout::joinedBytes() const {
  const Joined j = joinedLayout(table_.size(), booksBytes_, ranks_.size(), records_.size());
  std::vector<std::byte> out(j.end, std::byte{0});
  if (!table_.empty()) std::memcpy(out.data(), table_.data(), j.books);
  parallelFor(table_.size(), 0, [&](std::size_t s) {
    associateCodebooks(s, reinterpret_cast<float*>(out.data() + j.books + table_[s].codebookAt[0]));
  });
  if (!ranks_.empty()) std::memcpy(out.data() + j.ranks, ranks_.data(), ranks_.size() * 4);
  if (!occupancy_.empty())
    std::memcpy(out.data() + j.occupancy, occupancy_.data(), occupancy_.size());
  if (!records_.empty()) std::memcpy(out.data() + j.records, records_.data(), records_.size());
  return out;
}

kernels::TvqView Layout::view(const std::byte* base, int partitions) const {
  kernels::TvqView v = viewWith(*books_, partitions);
  if (!base) return v;
  const Joined j = joinedLayout(table_.size(), booksBytes_, ranks_.size(), records_.size());
  const auto* b = reinterpret_cast<const std::uint8_t*>(base);
  auto& d = v.decoder;
  d.table = reinterpret_cast<const kernels::TvqSubvolume*>(b);
  d.books = b + j.books, d.ranks = b + j.ranks, d.occupancy = b + j.occupancy;
  d.records = b + j.records;
  d.lazyBooks = nullptr, d.lazyOwner = nullptr;
  return v;
}

kernels::TvqView Layout::viewWith(const Books& books, int partitions) const {
  if (partitions < 0 || partitions > 3)
    throw std::invalid_argument("tvq: progressive level out of range");
  kernels::TvqView v;
  v.setDims(info_.dims.x, info_.dims.y, info_.dims.z);
  v.cacheId = cacheId_ + std::uint64_t(partitions);
  auto& d = v.decoder;
  d.table = table_.data();
  d.ranks = reinterpret_cast<const std::uint8_t*>(ranks_.data());
  d.occupancy = reinterpret_cast<const std::uint8_t*>(occupancy_.data());
  d.records = reinterpret_cast<const std::uint8_t*>(records_.data());
  d.lazyBooks = &Books::fetch, d.lazyOwner = &books;
  d.subvolumeBlocks = s_;
  d.subvolumesX = grid_.x, d.subvolumesY = grid_.y;
  d.dcBits = dcBits_;
  d.dcLo = float(dcLo_), d.dcStep = float(dcStep_);
  d.lo = float(info_.valueMin), d.hi = float(info_.valueMax);
  d.partitions = partitions;
  d.integral = info_.type != ScalarType::Float32;
  return v;
}

bool Layout::coefficients(int bx, int by, int bz, float* c) const {
  if (bx < 0 || by < 0 || bz < 0 || bx >= blocks_.x || by >= blocks_.y || bz >= blocks_.z)
    throw std::out_of_range("tvq: block outside the volume");
  for (int k = 0; k < kBlockVoxels; ++k) c[k] = 0;
  const kernels::TvqView v = view();
  const std::uint64_t key = v.decoder.key(bx, by, bz);
  const std::uint64_t si = key >> 32;
  const kernels::TvqSubvolume& t = v.decoder.subvolume(si);
  if ((key & 0xFFFFFFFFull) == kernels::TvqDecoder::kUncoded) {
    c[0] = 8.0f * t.background;
    return false;
  }
  std::uint32_t dc, k[3];
  v.decoder.codes(t, key & 0xFFFFFFFFull, dc, k);
  c[0] = 8.0f * float(dcLo_ + double(dc) * dcStep_);
  const Sub& sub = subvolumes_[si];
  const std::int16_t* book = reinterpret_cast<const std::int16_t*>(codebooks_.data());
  for (int p = 0; p < 3; ++p) {
    if (k[p] == 0) continue;  // the zero vector
    std::uint64_t index = k[p] - 1, value = sub.codebookAt[std::size_t(p)];
    for (int ch = 0; ch < chapterCount(p); ++ch) {
      const auto ks = chapterCoefficients(basis_, p, firstChapterClass(p) + ch);
      const std::uint64_t n = sub.chapters[std::size_t(p)][std::size_t(ch)];
      if (index < n) {
        value += index * ks.size();
        for (int kk : ks) {
          std::int16_t q;
          std::memcpy(&q, book + value++, 2);
          c[kk] = float(q) * sub.scale[std::size_t(p)];
        }
        break;
      }
      index -= n, value += n * ks.size();
    }
  }
  return true;
}

RangeGrid Layout::rangeGrid(int partitions) const {
  const Books scratch(*this);
  return brickRangeGrid(viewWith(scratch, partitions), info_.type);
}

Volume Layout::decode(int partitions) const {
  const Books scratch(*this);
  return decodeBricks(viewWith(scratch, partitions), info_.type, info_.spacing);
}

Volume decode(const VolumeInfo& info, const SectionSet& sections) {
  return Layout(info, sections).decode();
}

}  // namespace voxwall::codec::tvq
