#include "protocol/hkdf.h"

#include <openssl/evp.h>
#include <openssl/kdf.h>

namespace edgephys {

bool HkdfSha256(std::span<const uint8_t> salt, std::span<const uint8_t> ikm,
                std::span<const uint8_t> info, std::span<uint8_t> out) {
  size_t out_len = out.size();
  EVP_PKEY_CTX* ctx = EVP_PKEY_CTX_new_id(EVP_PKEY_HKDF, nullptr);
  const bool ok =
      ctx != nullptr && EVP_PKEY_derive_init(ctx) == 1 &&
      EVP_PKEY_CTX_set_hkdf_md(ctx, EVP_sha256()) == 1 &&
      (salt.empty() ||
       EVP_PKEY_CTX_set1_hkdf_salt(ctx, salt.data(), static_cast<int>(salt.size())) == 1) &&
      EVP_PKEY_CTX_set1_hkdf_key(ctx, ikm.data(), static_cast<int>(ikm.size())) == 1 &&
      EVP_PKEY_CTX_add1_hkdf_info(ctx, info.data(), static_cast<int>(info.size())) == 1 &&
      EVP_PKEY_derive(ctx, out.data(), &out_len) == 1 && out_len == out.size();
  EVP_PKEY_CTX_free(ctx);
  return ok;
}

}  // namespace edgephys
