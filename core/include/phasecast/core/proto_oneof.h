#pragma once
// The name of the field set in a protobuf oneof ("impulse", "list_scenes",
// ...), read from the message's descriptor: one answer for the server's
// error lines, the gateway's refusals and the fuzzers' tallies, which stays
// right when fields are added to proto/phasecast.proto.

#include <google/protobuf/message.h>

#include <string>

namespace phasecast::core {

// "" when no field of `oneof` is set or the message has no such oneof.
std::string oneof_case(const google::protobuf::Message& message, const char* oneof);

}  // namespace phasecast::core
