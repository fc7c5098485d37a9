// The wire schema as a protobufjs JSON descriptor, read from proto/phasecast.proto.
// Used at build time (build.mjs) and by the tests, so both decode with the
// same descriptor the page is bundled with. Field names keep the .proto's
// snake_case (q_u, q_a, content_hash): the page uses the paper's names.
import protobuf from 'protobufjs';
import { fileURLToPath } from 'node:url';
import path from 'node:path';

export const protoPath = fileURLToPath(new URL('../../proto/phasecast.proto', import.meta.url));

export function loadDescriptor(file = protoPath) {
  const root = new protobuf.Root();
  root.loadSync(path.resolve(file), { keepCase: true });
  return root.toJSON({ keepComments: false });
}
