# Sourced by the scripts that run node with pinned npm modules.
# npm_ci_once: in the current directory, installs the modules package-lock.json pins (`npm ci`)
# when node_modules is missing or was installed from another lock file. A lock file next to
# node_modules (.npm-ci.lock, flock) makes parallel runs install once; after that no network.
npm_ci_once() {
  cmp -s package-lock.json node_modules/.edgephys-lock 2>/dev/null && return 0
  local fd
  exec {fd}>".npm-ci.lock"
  flock "$fd"
  if ! cmp -s package-lock.json node_modules/.edgephys-lock 2>/dev/null; then
    npm ci --no-audit --no-fund --loglevel=error
    cp package-lock.json node_modules/.edgephys-lock
  fi
  flock -u "$fd"
  exec {fd}>&-
}
