/* Consumer of the installed SDK: prints the library's version and ABI, and with a relay
 * address, a join token and a room, connects, joins, spawns one entity and leaves.
 *   consumer [<relay host:port> <token> <room>]
 * Prints "consumer ok" and exits 0 on success. */
#define _POSIX_C_SOURCE 200809L
#include <edgephys/edgephys.h>

#include <stdio.h>
#include <time.h>

static int Wait(edgephys_client* c, uint32_t type, double timeout_s) {
  const double end = edgephys_now_s() + timeout_s;
  while (edgephys_now_s() < end) {
    edgephys_event ev;
    if (edgephys_client_update(c, edgephys_now_s()) != EDGEPHYS_OK) return 0;
    while (edgephys_client_poll_event(c, &ev) == EDGEPHYS_OK && ev.type != EDGEPHYS_EVENT_NONE) {
      if (ev.type == type) return 1;
    }
    struct timespec ts = {0, 10000000};
    nanosleep(&ts, NULL);
  }
  return 0;
}

int main(int argc, char** argv) {
  printf("edgephys %s ABI %u (header ABI %u)\n", edgephys_version_string(), edgephys_abi_version(),
         EDGEPHYS_ABI_VERSION);
  if (edgephys_abi_version() != EDGEPHYS_ABI_VERSION) return 1;
  if (argc == 4) {
    edgephys_client_config cfg;
    edgephys_client* c = NULL;
    edgephys_spawn_desc d;
    uint32_t id = 0;
    edgephys_client_config_init(&cfg);
    if (edgephys_client_create(&cfg, &c) != EDGEPHYS_OK ||
        edgephys_client_connect(c, argv[1], argv[2], edgephys_now_s()) != EDGEPHYS_OK ||
        !Wait(c, EDGEPHYS_EVENT_CONNECTED, 5) || edgephys_client_join(c, argv[3]) != EDGEPHYS_OK ||
        !Wait(c, EDGEPHYS_EVENT_JOINED, 5)) {
      printf("consumer FAILED: %s\n", edgephys_last_error());
      return 1;
    }
    edgephys_spawn_desc_init(&d);
    if (edgephys_client_spawn(c, &d, &id) != EDGEPHYS_OK) {
      printf("consumer FAILED to spawn: %s\n", edgephys_last_error());
      return 1;
    }
    printf("joined %s, spawned entity %u\n", argv[3], id);
    edgephys_client_destroy(c);
  }
  printf("consumer ok\n");
  return 0;
}
