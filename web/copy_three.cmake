# Copies three.js's module build and OrbitControls (the only files the page imports) into the
# page directory; the page maps the bare "three" import to them with an import map.
# Missing files fail the build: a build that succeeds with a page that cannot load is worse
# than one that says what to install.
foreach(f build/three.module.js examples/jsm/controls/OrbitControls.js)
  if(NOT EXISTS ${SRC}/${f})
    message(FATAL_ERROR "three.js not found: ${SRC}/${f} is missing, so the live page could "
                        "not load. Run scripts/deps.sh (it installs web/node_modules with npm ci) "
                        "and build again.")
  endif()
endforeach()
file(COPY ${SRC}/build/three.module.js DESTINATION ${DST})
file(COPY ${SRC}/examples/jsm/controls/OrbitControls.js DESTINATION ${DST})
