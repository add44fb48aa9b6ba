# Copies three.js's module build and OrbitControls (the only files the page imports) into the
# page directory; the page maps the bare "three" import to them with an import map.
if(NOT EXISTS ${SRC}/build/three.module.js)
  message(WARNING "three.js not found in ${SRC} (run scripts/deps.sh): the live page will not load")
  return()
endif()
file(COPY ${SRC}/build/three.module.js DESTINATION ${DST})
file(COPY ${SRC}/examples/jsm/controls/OrbitControls.js DESTINATION ${DST})
