/* Stands in for libOSMesa on a GPU machine: phasecast-render links it, but
   the EGL backend never calls it. Every call fails, so a run that asks for
   --backend osmesa there says "cannot create an OSMesa context". */
#include <stddef.h>

typedef void* OSMesaContext;

OSMesaContext OSMesaCreateContextAttribs(const int* attributes, OSMesaContext share) {
  (void)attributes;
  (void)share;
  return NULL;
}
void OSMesaDestroyContext(OSMesaContext context) { (void)context; }
unsigned char OSMesaMakeCurrent(OSMesaContext context, void* buffer, unsigned type, int width, int height) {
  (void)context;
  (void)buffer;
  (void)type;
  (void)width;
  (void)height;
  return 0;
}
void* OSMesaGetProcAddress(const char* name) {
  (void)name;
  return NULL;
}
