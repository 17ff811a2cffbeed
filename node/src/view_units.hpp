// The raycaster's view types, split over translation units: node/CMakeLists.txt writes
// VOXWALL_VIEW_UNITS of them from cpu_view.cpp.in (and, with CUDA, from cuda_view.cu.in), and unit
// u compiles the views u, u + units, u + 2 units, ... of ViewVariant (codec::AnyView). The
// heaviest code of the build compiles on every core, and a codec that adds view types needs no
// edit here: its views join the units round-robin.
#pragma once

#include <cstddef>
#include <type_traits>
#include <utility>
#include <variant>
#include <voxwall/node/render_volume.hpp>

namespace voxwall::node {

inline constexpr std::size_t kViewUnits = VOXWALL_VIEW_UNITS;
static_assert(kViewUnits > 0);

namespace detail {
template <class T, class Variant>
struct ViewIndex;
template <class T, class... V>
struct ViewIndex<T, std::variant<V...>> {
  static constexpr std::size_t value = [] {
    constexpr bool same[] = {std::is_same_v<T, V>...};
    for (std::size_t i = 0; i < sizeof...(V); ++i)
      if (same[i]) return i;
    return sizeof...(V);
  }();
  static_assert(value < sizeof...(V), "not a view type of ViewVariant");
};
template <std::size_t Unit, class F, std::size_t... K>
void forEachViewOfUnit(F& f, std::index_sequence<K...>) {
  (f(std::integral_constant<std::size_t, Unit + K * kViewUnits>{}), ...);
}
}  // namespace detail

// The index of view type `View` in ViewVariant, and the unit that compiles it.
template <class View>
inline constexpr std::size_t kViewIndex = detail::ViewIndex<View, ViewVariant>::value;
template <class View>
inline constexpr std::size_t kViewUnit = kViewIndex<View> % kViewUnits;

// Calls f(std::integral_constant<std::size_t, I>{}) for every view index I that unit `Unit`
// compiles (none when there are fewer views than units).
template <std::size_t Unit, class F>
void forEachViewOfUnit(F&& f) {
  constexpr std::size_t views = std::variant_size_v<ViewVariant>;
  constexpr std::size_t count = Unit < views ? (views - Unit + kViewUnits - 1) / kViewUnits : 0;
  detail::forEachViewOfUnit<Unit>(f, std::make_index_sequence<count>{});
}

}  // namespace voxwall::node
