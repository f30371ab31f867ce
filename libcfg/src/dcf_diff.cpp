#include "cfg/dcf_diff.hpp"

#include <map>
#include <string_view>
#include <utility>

#include "cfg/data_type.hpp"
#include "cfg/dynamic_channels.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/value.hpp"

namespace cfg {
namespace {

// A parameter as the download would write it: typed when it parses, else the text.
struct Parameter {
  std::optional<Value> value;
  std::string text;  // as written, when there is a value at all
  bool present = false;
  int line = 0;
};

Parameter parameter_of(const SubObject& sub, std::optional<std::uint8_t> node_id) {
  Parameter p;
  const OptionalText& text = sub.configured_value();
  const int value_line = sub.parameter_value ? sub.parameter_value_line : sub.default_value_line;
  p.line = value_line != 0 ? value_line : sub.line;
  // CANopenEditor writes "ParameterValue=" for entries it does not configure: no value.
  if (!text || text->empty()) return p;
  p.present = true;
  p.text = *text;
  if (const auto type = sub.basic_type()) {
    if (!mentions_node_id(*text) || node_id) {
      if (auto parsed = parse_value(*type, *text, node_id)) p.value = std::move(parsed).value();
    }
  }
  return p;
}

bool same(const Parameter& a, const Parameter& b) {
  if (a.present != b.present) return false;
  if (!a.present) return true;
  if (a.value && b.value)
    return a.value->type() == b.value->type() && encode(*a.value) == encode(*b.value);
  if (a.value || b.value) return false;
  return a.text == b.text;
}

DiffSide side_of(const Parameter& p) {
  if (!p.present) return {"(no value)", p.line};
  if (p.value) return {describe_value(*p.value), p.line};
  return {"'" + p.text + "' (as written)", p.line};
}

// A segment in words, every field §8.4 gives it.
std::string segment_text(const DynamicSegment& s) {
  const DataTypeInfo* type = find_data_type(s.data_type);
  std::string text = type != nullptr ? std::string(type->name) : cfg::hex(s.data_type, 4) + "h";
  text += " " + std::string(to_string(s.direction)) + " " + object_name(s.first_index);
  if (s.last_index != s.first_index) text += "-" + object_name(s.last_index);
  text += ", PPOffset " + std::to_string(s.pp_offset);
  if (s.bit_distance) text += " (bit distance " + std::to_string(*s.bit_distance) + ")";
  text += ", MaxCnt " + std::to_string(s.max_count);
  if (s.m_specific) text += ", MSpecific '" + *s.m_specific + "'";
  return text;
}

}  // namespace

std::vector<SegmentDifference> diff_dynamic_channels(const DeviceDescription& a,
                                                     const DeviceDescription& b) {
  const auto segments_a = dynamic_channels_of(a).value_or(DynamicChannels{}).segments;
  const auto segments_b = dynamic_channels_of(b).value_or(DynamicChannels{}).segments;
  // By range start: N of each side (1-based).
  std::map<std::uint16_t, std::pair<std::size_t, std::size_t>> by_start;
  for (std::size_t i = 0; i < segments_a.size(); ++i)
    by_start[segments_a[i].first_index].first = i + 1;
  for (std::size_t i = 0; i < segments_b.size(); ++i)
    by_start[segments_b[i].first_index].second = i + 1;
  using Kind = ParameterDifference::Kind;
  std::vector<SegmentDifference> out;
  for (const auto& [start, n] : by_start) {
    const auto [na, nb] = n;
    if (na != 0 && nb != 0 && segments_a[na - 1] == segments_b[nb - 1]) continue;
    SegmentDifference d;
    d.kind = na == 0 ? Kind::OnlyInB : nb == 0 ? Kind::OnlyInA : Kind::Changed;
    d.first_index = start;
    d.segment_a = na;
    d.segment_b = nb;
    if (na != 0) d.a = DiffSide{segment_text(segments_a[na - 1]), 0};
    if (nb != 0) d.b = DiffSide{segment_text(segments_b[nb - 1]), 0};
    out.push_back(std::move(d));
  }
  return out;
}

std::string parameter_name(const Object& object, const SubObject& sub) {
  if (object.is_var() || sub.name.empty()) return object.name;
  return object.name + " / " + sub.name;
}

std::string_view to_string(ParameterDifference::Kind kind) {
  switch (kind) {
    case ParameterDifference::Kind::Changed:
      return "changed";
    case ParameterDifference::Kind::OnlyInA:
      return "only_in_a";
    case ParameterDifference::Kind::OnlyInB:
      return "only_in_b";
  }
  return "changed";
}

std::vector<ParameterDifference> diff_parameters(const DeviceDescription& a,
                                                 const DeviceDescription& b,
                                                 const DiffOptions& options) {
  const auto node_a = options.node_id_a ? options.node_id_a : a.node_id();
  const auto node_b = options.node_id_b ? options.node_id_b : b.node_id();
  std::vector<ParameterDifference> out;
  using Kind = ParameterDifference::Kind;

  const auto only = [&out](Kind kind, const Object& object, const SubObject* sub,
                           const Parameter& p) {
    ParameterDifference d;
    d.kind = kind;
    d.address = {object.index, sub != nullptr ? sub->sub_index : std::uint8_t{0}};
    d.whole_object = sub == nullptr;
    d.name = sub != nullptr ? parameter_name(object, *sub) : object.name;
    const DiffSide side = sub != nullptr ? side_of(p) : DiffSide{"", object.line};
    (kind == Kind::OnlyInA ? d.a : d.b) = side;
    out.push_back(std::move(d));
  };

  auto ia = a.objects.begin();
  auto ib = b.objects.begin();
  while (ia != a.objects.end() || ib != b.objects.end()) {
    if (ib == b.objects.end() || (ia != a.objects.end() && ia->first < ib->first)) {
      only(Kind::OnlyInA, ia->second, nullptr, {});
      ++ia;
      continue;
    }
    if (ia == a.objects.end() || ib->first < ia->first) {
      only(Kind::OnlyInB, ib->second, nullptr, {});
      ++ib;
      continue;
    }
    const Object& oa = ia->second;
    const Object& ob = ib->second;
    auto sa = oa.subs.begin();
    auto sb = ob.subs.begin();
    while (sa != oa.subs.end() || sb != ob.subs.end()) {
      if (sb == ob.subs.end() || (sa != oa.subs.end() && sa->first < sb->first)) {
        only(Kind::OnlyInA, oa, &sa->second, parameter_of(sa->second, node_a));
        ++sa;
        continue;
      }
      if (sa == oa.subs.end() || sb->first < sa->first) {
        only(Kind::OnlyInB, ob, &sb->second, parameter_of(sb->second, node_b));
        ++sb;
        continue;
      }
      const Parameter pa = parameter_of(sa->second, node_a);
      const Parameter pb = parameter_of(sb->second, node_b);
      if (!same(pa, pb)) {
        ParameterDifference d;
        d.address = {oa.index, sa->first};
        d.name = parameter_name(oa, sa->second);
        d.a = side_of(pa);
        d.b = side_of(pb);
        out.push_back(std::move(d));
      }
      ++sa;
      ++sb;
    }
    ++ia;
    ++ib;
  }
  return out;
}

}  // namespace cfg
