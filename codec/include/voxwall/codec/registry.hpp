// The codecs this build carries: the one place a codec is registered. Each entry names the view
// types its payloads produce (`Views`) and returns its Codec object (codec.hpp, `instance()`);
// the raycaster is instantiated for every view listed here (AnyView), on the CPU and under CUDA.
#pragma once

#include <string>
#include <variant>
#include <voxwall/codec/codec.hpp>
#include <voxwall/codec/ksvd_codec.hpp>
#include <voxwall/codec/raw_codec.hpp>
#include <voxwall/codec/svmm_codec.hpp>
#include <voxwall/codec/tvq_codec.hpp>
#include <voxwall/codec/vq_codec.hpp>
#include <voxwall/codec/zfp_codec.hpp>

namespace voxwall::codec {

template <class... Codecs>
struct CodecList;

namespace detail {
template <class... Lists>
struct ConcatViews;
template <class... A>
struct ConcatViews<ViewList<A...>> {
  using type = std::variant<A...>;
};
template <class... A, class... B, class... Rest>
struct ConcatViews<ViewList<A...>, ViewList<B...>, Rest...>
    : ConcatViews<ViewList<A..., B...>, Rest...> {};

template <class T, std::size_t N>
constexpr bool distinct(const T (&values)[N]) {
  for (std::size_t i = 0; i < N; ++i)
    for (std::size_t j = 0; j < i; ++j)
      if (values[i] == values[j]) return false;
  return true;
}

template <class... V>
constexpr bool hasTraversalView(ViewList<V...>) {
  return (requires { V::kTraversal; } || ...);
}
}  // namespace detail

template <class... Codecs>
struct CodecList {
  static_assert(detail::distinct({std::uint32_t(Codecs::kId)...}),
                "two registered codecs have the same id (kId)");
  static_assert(detail::distinct({Codecs::kName...}), "two registered codecs have the same name");
  // Whether codec `id` has a view that traverses mip levels (kTraversal: --lod, nearest).
  static bool hasMipLevels(CodecId id) {
    return ((Codecs::instance().id() == id && detail::hasTraversalView(typename Codecs::Views{})) ||
            ...);
  }
  // The names of those codecs, ", "-separated.
  static std::string traversalCodecNames() {
    std::string names;
    ((detail::hasTraversalView(typename Codecs::Views{})
          ? void(names += (names.empty() ? "" : ", ") + std::string(Codecs::instance().name()))
          : void()),
     ...);
    return names;
  }
  // Every view type of every codec, in registration order.
  using AnyView = typename detail::ConcatViews<typename Codecs::Views...>::type;
  // One object per codec, in registration order.
  static const std::vector<const Codec*>& objects() {
    static const std::vector<const Codec*> list{&Codecs::instance()...};
    return list;
  }
};

// ---- The registration line: add a codec's class here (and include its header above). ----
using RegisteredCodecs = CodecList<raw::RawCodecEntry, vq::VqCodecEntry, svmm::SvmmCodecEntry,
                                   ksvd::KsvdCodecEntry, tvq::TvqCodecEntry, zfp::ZfpCodecEntry>;

using AnyView = RegisteredCodecs::AnyView;

}  // namespace voxwall::codec
