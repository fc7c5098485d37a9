#include "phasecast/server/topic_interest.h"

#include "phasecast/server/wire.h"

namespace phasecast::server {
namespace {

constexpr std::string_view kInstancePrefix = "inst/";

}  // namespace

void TopicInterest::set(std::set<std::string> prefixes) {
  prefixes_ = std::move(prefixes);
  instance_cache_.clear();
  topic_cache_.clear();
  instances_ = Instances::none;
  for (const auto& p : prefixes_) {
    if (kInstancePrefix.starts_with(p)) {
      instances_ = Instances::all;
      return;
    }
    if (p.starts_with(kInstancePrefix)) instances_ = Instances::some;
  }
}

// Each prefix of the topic looked up (topics are short), so many subscribed
// prefixes cost no more than a few.
bool TopicInterest::matches(std::string_view topic) const {
  for (std::size_t n = 0; n <= topic.size(); ++n) {
    if (prefixes_.contains(std::string(topic.substr(0, n)))) return true;
  }
  return false;
}

bool TopicInterest::wants(std::string_view topic) {
  const auto [it, fresh] = topic_cache_.try_emplace(std::string(topic), false);
  if (fresh) it->second = matches(topic);
  return it->second;
}

bool TopicInterest::wants_instance(std::uint32_t instance) {
  if (instances_ != Instances::some) return instances_ == Instances::all;
  const auto [it, fresh] = instance_cache_.try_emplace(instance, false);
  if (fresh) it->second = matches(instance_topic(instance));
  return it->second;
}

}  // namespace phasecast::server
