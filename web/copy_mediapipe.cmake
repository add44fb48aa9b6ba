# Copies MediaPipe Pose (npm @mediapipe/pose: its loader, WASM, graph and model weights) into
# the page directory's mediapipe/, where the Camera button's locateFile points: the live server
# serves them, nothing comes from a CDN. The heavy landmark model (27 MB) is left out: the page
# uses modelComplexity 1 (full). A missing package is a warning, not an error: the page works
# without it and its Camera button says to run scripts/deps.sh.
set(files pose.js pose_solution_packed_assets_loader.js pose_solution_packed_assets.data
    pose_solution_simd_wasm_bin.js pose_solution_simd_wasm_bin.wasm
    pose_solution_simd_wasm_bin.data pose_solution_wasm_bin.js pose_solution_wasm_bin.wasm
    pose_web.binarypb pose_landmark_full.tflite pose_landmark_lite.tflite)
foreach(f ${files})
  if(NOT EXISTS ${SRC}/${f})
    message(WARNING "MediaPipe Pose not found (${SRC}/${f} is missing): the live page's Camera "
                    "button will not work. Run scripts/deps.sh (npm ci in web/) and build again.")
    return()
  endif()
endforeach()
file(MAKE_DIRECTORY ${DST}/mediapipe)
foreach(f ${files})
  file(COPY ${SRC}/${f} DESTINATION ${DST}/mediapipe)
endforeach()
