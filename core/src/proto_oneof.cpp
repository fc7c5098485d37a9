#include "phasecast/core/proto_oneof.h"

namespace phasecast::core {

std::string oneof_case(const google::protobuf::Message& message, const char* oneof) {
  const auto* decl = message.GetDescriptor()->FindOneofByName(oneof);
  const auto* field = decl ? message.GetReflection()->GetOneofFieldDescriptor(message, decl) : nullptr;
  return field ? field->name() : "";
}

}  // namespace phasecast::core
