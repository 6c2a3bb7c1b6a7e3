# cmake -DIN=file -DOUT=header -DNAME=symbol -P EmbedFile.cmake
# Writes a header with `inline constexpr char NAME[] = R"...(contents)...";`
file(READ ${IN} CONTENT)
file(WRITE ${OUT} "// Generated from ${IN}; do not edit.\n#pragma once\ninline constexpr char ${NAME}[] = R\"magnav_xml(${CONTENT})magnav_xml\";\n")
