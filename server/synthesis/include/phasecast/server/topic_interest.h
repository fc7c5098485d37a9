#pragma once
// Which published topics someone listens to. ZeroMQ matches a subscription
// as a prefix of the topic, so a topic is wanted when any subscribed prefix
// starts it. The server's XPUB socket reports subscriptions as they come and
// go; the tick then builds only wanted messages (45 000 instances nobody
// follows one by one cost no Frame messages). Answers are cached per topic
// until the subscriptions change.

#include <cstdint>
#include <set>
#include <string>
#include <string_view>
#include <unordered_map>

namespace phasecast::server {

class TopicInterest {
 public:
  // Replaces the subscribed prefixes. Until then "inst/": every instance's
  // Frame and no batch, what tests and benchmarks that read the tick expect.
  void set(std::set<std::string> prefixes);
  bool wants(std::string_view topic);
  // The Frame topic of an instance ("inst/<id>/"), without formatting it
  // when no subscription reaches below "inst/".
  bool wants_instance(std::uint32_t instance);

 private:
  bool matches(std::string_view topic) const;

  std::set<std::string> prefixes_{"inst/"};
  // Instance topics: all wanted (a prefix of "inst/" is subscribed), none, or look up.
  enum class Instances { all, none, some } instances_ = Instances::all;
  std::unordered_map<std::uint32_t, bool> instance_cache_;
  std::unordered_map<std::string, bool> topic_cache_;
};

}  // namespace phasecast::server
