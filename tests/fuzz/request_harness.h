#pragma once
// Request fuzzing of phasecast::server::SynthesisService::handle(bytes): the
// service under test with its invariants (RequestHarness), the seed requests
// of every kind, and mutations that know the phasecast.v1.Request schema.

#include "fuzz_support.h"
#include "phasecast/proto/phasecast.pb.h"
#include "phasecast/server/synthesis_service.h"

#include <google/protobuf/message.h>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace phasecast::fuzz {

// What one input did: `violation` is empty unless an invariant broke;
// `note` names a lesser defect (a protocol promise kept loosely, e.g. an
// error reply of several lines); `kind` sorts the reply for the tallies
// ("ok basis", "error impulse: ...").
struct RequestVerdict {
  std::string violation;
  std::string note;
  std::string kind;
};

class RequestHarness {
 public:
  // A service at 60 Hz with `packages` loaded and one instance of the first
  // one's scene; recordings that inputs start go to `work_dir`.
  RequestHarness(const std::vector<std::filesystem::path>& packages, const std::filesystem::path& work_dir);

  // Feeds `bytes` from `client` ("" for none) to handle() and checks:
  // nothing escapes, exactly one
  // request is counted, the reply carries the request's id (0 when the bytes
  // do not parse), ok <=> no error, the result matches the request's kind,
  // an error names that kind, a basis chunk lies within its part.
  RequestVerdict run(std::string_view bytes, const std::string& client = {});
  // One tick of synthetic time: nothing escapes, one frame per instance.
  std::string tick();
  // Creates an instance when none is left, so impulses have a target.
  std::string top_up();
  // Bounds what a long run accumulates: instances beyond 64 are destroyed
  // (through handle(), checked like any input), recordings stopped and removed.
  std::string tidy();
  // What the service did over the run: frames published, impulses applied
  // and refused, most instances alive at once.
  std::string activity() const;

  // Well-formed serialized requests of every kind, for the corpus.
  std::vector<Bytes> seeds() const;
  // Words worth writing into fields: scene and palette names, live instance
  // ids, their next frames, palette indices.
  std::vector<std::string> names() const;
  std::vector<std::uint64_t> instance_ids() const;
  std::vector<std::uint64_t> frames() const;
  int palette_size() const;

 private:
  std::string check(const v1::Request* request, const v1::Reply& reply, const server::ServiceStats& before,
                    const server::ServiceStats& after) const;
  std::string scene() const;

  // mutable: the service offers engine() only non-const; the const members just read it.
  mutable server::SynthesisService service_;
  std::filesystem::path work_dir_;
  std::uint64_t next_id_ = 1u << 31;  // ids of the harness's own requests
  std::size_t most_instances_ = 0;
};

// Mutations that keep (or deliberately break) the Request schema: a field
// anywhere in the message set to a boundary value or a known name, the body
// switched to another kind, fields cleared, requests concatenated (protobuf
// merges them), unknown fields and broken varints appended.
class RequestMutator {
 public:
  RequestMutator(Random& random, const RequestHarness& harness) : random_(random), harness_(harness) {}
  Bytes mutate(const Bytes& parent, const Bytes& other);

 private:
  void mutate_message(google::protobuf::Message& m, int depth);
  void set_field(google::protobuf::Message& m, const google::protobuf::FieldDescriptor* f, int depth);
  std::uint64_t number(const std::string& field);
  std::string text();
  void append_wire_noise(Bytes& data);
  void retarget(google::protobuf::Message& m);

  Random& random_;
  const RequestHarness& harness_;
};

}  // namespace phasecast::fuzz
