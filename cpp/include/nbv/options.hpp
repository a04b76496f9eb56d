/* Options structs declared once. An options struct lists its fields in one X-macro,

     #define NBV_FOO_OPTIONS(X)                                        \
       X(double, radius, 0.8, "collision radius, m")                   \
       X(bool, check_segment, true, "the straight flight must be clear")
     struct FooOptions {
       NBV_FOO_OPTIONS(NBV_DECLARE_OPTION)
       void validate() const;
     };

   and everything else - the pybind11 class, its keyword constructor, to_dict, the documentation
   of each field, and through them the Python configuration's defaults and the generated
   configs/default.yaml - is expanded from that list (cpp/bindings/options.hpp). A field is
   named, typed, defaulted and documented in exactly one place. */
#pragma once

#define NBV_DECLARE_OPTION(type, name, default_value, doc) type name = default_value;
