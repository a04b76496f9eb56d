// Binding of an options struct declared with an X-macro field list (nbv/options.hpp):
//
//   OptionsClass<FooOptions> binder(m, "FooOptions", "doc");
//   using S = FooOptions;
//   NBV_FOO_OPTIONS(NBV_BIND_FIELD)
//   binder.finish();
//
// gives a Python class with one property per field (documented from the list), a keyword-only
// constructor starting from the C++ defaults (an unknown keyword raises TypeError naming it),
// `to_dict()`, `fields()` (name -> documentation), `copy(**changes)`, equality, a repr and
// pickling (copy.copy / copy.deepcopy too), and runs the struct's validate() (ValueError)
// whenever it is built or changed through them.
// options_arg() accepts an instance, a dict of fields or None wherever a binding takes options.
#pragma once

#include "bindings.hpp"
#include "nbv/workspace_grid.hpp"

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace nbv::bind {

template <typename F>
struct OptionField {
  static py::object get(const F& v) { return py::cast(v); }
  static F set(const py::handle& h, const std::string& name) {
    try {
      return h.cast<F>();
    } catch (const py::cast_error&) {
      throw py::type_error("option '" + name + "' cannot be " +
                           std::string(py::str(py::type::of(h).attr("__name__"))));
    }
  }
};

template <>
struct OptionField<double> {
  static py::object get(double v) { return py::float_(v); }
  static double set(const py::handle& h, const std::string& name) {
    if (py::isinstance<py::bool_>(h) ||
        !(py::isinstance<py::float_>(h) || py::isinstance<py::int_>(h)))
      throw py::type_error("option '" + name + "' must be a number");
    return h.cast<double>();
  }
};

template <>
struct OptionField<int> {
  static py::object get(int v) { return py::int_(v); }
  static int set(const py::handle& h, const std::string& name) {
    if (py::isinstance<py::bool_>(h) || !py::isinstance<py::int_>(h))
      throw py::type_error("option '" + name + "' must be an integer");
    const long long v = h.cast<long long>();
    if (v < -2147483647LL || v > 2147483647LL)
      throw py::value_error("option '" + name + "' is out of range: " + std::to_string(v));
    return int(v);
  }
};

template <>
struct OptionField<bool> {
  static py::object get(bool v) { return py::bool_(v); }
  static bool set(const py::handle& h, const std::string& name) {
    if (!py::isinstance<py::bool_>(h)) throw py::type_error("option '" + name + "' must be a bool");
    return h.cast<bool>();
  }
};

template <>
struct OptionField<std::uint64_t> {
  static py::object get(std::uint64_t v) { return py::int_(v); }
  static std::uint64_t set(const py::handle& h, const std::string& name) {
    return seed_arg(h, ("option '" + name + "'").c_str());
  }
};

template <>
struct OptionField<std::vector<double>> {
  static py::object get(const std::vector<double>& v) { return py::cast(v); }
  static std::vector<double> set(const py::handle& h, const std::string& name) {
    std::vector<double> out;
    if (py::isinstance<py::str>(h) || !py::isinstance<py::sequence>(h))
      throw py::type_error("option '" + name + "' must be a list of numbers");
    for (const auto& x : h.cast<py::sequence>()) out.push_back(OptionField<double>::set(x, name));
    return out;
  }
};

template <>
struct OptionField<Eigen::Vector3d> {
  static py::object get(const Eigen::Vector3d& v) { return py::cast(Eigen::Vector3d(v)); }
  static Eigen::Vector3d set(const py::handle& h, const std::string& name) {
    py::array_t<double, py::array::c_style | py::array::forcecast> a;
    try {
      const py::array given = py::array::ensure(h);
      if (given) require_real_dtype(given, "option '" + name + "'");
      a = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(h);
    } catch (const py::error_already_set&) {
      a = {};
    }
    if (!a || a.size() != 3) throw py::value_error("option '" + name + "' must be 3 numbers");
    const Eigen::Vector3d v(a.data()[0], a.data()[1], a.data()[2]);
    if (v.hasNaN()) throw py::value_error("option '" + name + "' contains NaN");
    return v;
  }
};

template <>
struct OptionField<Eigen::Isometry3d> {
  static py::object get(const Eigen::Isometry3d& v) {
    return py::cast(Eigen::Matrix4d(v.matrix()));
  }
  static Eigen::Isometry3d set(const py::handle& h, const std::string& name) {
    return transform_arg(h, name.c_str());
  }
};

template <>
struct OptionField<EntropyUnit> {
  static py::object get(EntropyUnit u) { return py::str(u == EntropyUnit::Bits ? "bits" : "nats"); }
  static EntropyUnit set(const py::handle& h, const std::string& name) {
    const std::string s = py::isinstance<py::str>(h) ? h.cast<std::string>() : std::string();
    if (s == "nats" || s == "nat") return EntropyUnit::Nats;
    if (s == "bits" || s == "bit") return EntropyUnit::Bits;
    throw py::value_error("option '" + name + "' must be 'nats' or 'bits'");
  }
};

template <typename T>
class OptionsClass {
 public:
  OptionsClass(py::handle scope, const char* name, const char* doc) : cls_(scope, name, doc) {}

  template <typename F>
  OptionsClass& field(const char* name, F T::*member, const char* doc) {
    const std::string n = name;
    names_.push_back(n);
    docs_[n] = doc;
    cls_.def_property(
        name, [member](const T& o) { return OptionField<F>::get(o.*member); },
        [member, n](T& o, const py::handle& v) {
          T copy = o;
          copy.*member = OptionField<F>::set(v, n);
          copy.validate();
          o = copy;
        },
        doc);
    setters_[n] = [member, n](T& o, const py::handle& v) { o.*member = OptionField<F>::set(v, n); };
    getters_[n] = [member](const T& o) { return OptionField<F>::get(o.*member); };
    return *this;
  }

  py::class_<T>& finish() {
    auto names = names_;
    auto docs = docs_;
    auto setters = setters_;
    auto getters = getters_;
    const std::string type_name = py::str(cls_.attr("__name__"));
    auto apply = [setters, names, type_name](T& o, const py::dict& kw) {
      for (auto item : kw) {
        const std::string key = py::str(item.first);
        auto it = setters.find(key);
        if (it == setters.end()) {
          std::string known;
          for (const auto& n : names) known += (known.empty() ? "" : ", ") + n;
          throw py::type_error("unknown " + type_name + " option '" + key + "' (known: " + known +
                               ")");
        }
        it->second(o, item.second);
      }
      o.validate();
    };
    cls_.def(py::init([apply](const py::kwargs& kw) {
               T o;
               apply(o, kw);
               return o;
             }),
             ("Keyword arguments set fields by name (the rest keep their C++ defaults); unknown "
              "names raise TypeError, bad values ValueError."));
    cls_.def(
        "copy",
        [apply](const T& o, const py::kwargs& kw) {
          T c = o;
          apply(c, kw);
          return c;
        },
        "A copy with some fields changed (keyword arguments, as the constructor).");
    auto to_dict = [names, getters](const T& o) {
      py::dict d;
      for (const auto& n : names) d[py::str(n)] = getters.at(n)(o);
      return d;
    };
    cls_.def("to_dict", to_dict, "Every field by name (vectors as numpy arrays).");
    // pickle, copy.copy and copy.deepcopy: as its fields, rebuilt (and validated) as the
    // constructor does
    cls_.def(py::pickle(to_dict, [apply](const py::dict& d) {
      T o;
      apply(o, d);
      return o;
    }));
    cls_.def_static(
        "fields",
        [names, docs]() {
          py::dict d;
          for (const auto& n : names) d[py::str(n)] = docs.at(n);
          return d;
        },
        "Each field's documentation, by name, in declaration order.");
    cls_.def("__eq__", [names, getters](const T& a, const T& b) {
      const py::object array_equal = py::module_::import("numpy").attr("array_equal");
      for (const auto& n : names) {
        py::object x = getters.at(n)(a), y = getters.at(n)(b);
        const bool same =
            py::isinstance<py::array>(x) ? array_equal(x, y).template cast<bool>() : x.equal(y);
        if (!same) return false;
      }
      return true;
    });
    cls_.def("__repr__", [names, getters, type_name](const T& o) {
      std::string s = type_name + "(";
      for (std::size_t i = 0; i < names.size(); ++i) {
        py::object v = getters.at(names[i])(o);
        if (py::isinstance<py::array>(v)) v = v.attr("tolist")();
        s += (i ? ", " : "") + names[i] + "=" + std::string(py::repr(v));
      }
      return s + ")";
    });
    return cls_;
  }

  /// The options a binding was given: an instance, a dict of fields, or None (defaults).
  static T from(const py::handle& obj, const char* what) {
    if (obj.is_none()) return T{};
    if (py::isinstance<T>(obj)) return obj.cast<T>();
    if (py::isinstance<py::dict>(obj)) {
      py::object cls = py::type::of<T>();
      return cls(**obj.cast<py::dict>()).template cast<T>();
    }
    throw py::type_error(std::string(what) + " must be a " +
                         std::string(py::str(py::type::of<T>().attr("__name__"))) +
                         ", a dict of its fields, or None");
  }

 private:
  py::class_<T> cls_;
  std::vector<std::string> names_;
  std::map<std::string, std::string> docs_;
  std::map<std::string, std::function<void(T&, const py::handle&)>> setters_;
  std::map<std::string, std::function<py::object(const T&)>> getters_;
};

/// X-macro expander: one .field() of the OptionsClass `binder` per option of the struct `S`.
#define NBV_BIND_FIELD(type, name, default_value, doc) binder.field(#name, &S::name, doc);

/// The options a binding was given: `options` (an instance, a dict or None) with keyword
/// overrides on top; a keyword set to None keeps the value. Unknown names and values of the wrong
/// type raise ValueError, as bad values do.
template <typename Opt>
Opt options_with_keywords(const py::object& options, const py::kwargs& kw) {
  py::dict changes;
  for (const auto& item : kw)
    if (!item.second.is_none()) changes[item.first] = item.second;
  try {
    Opt o = OptionsClass<Opt>::from(options, "options");
    if (py::len(changes)) o = py::cast(o).attr("copy")(**changes).template cast<Opt>();
    return o;
  } catch (py::error_already_set& e) {
    if (e.matches(PyExc_TypeError)) throw py::value_error(py::str(e.value()).cast<std::string>());
    throw;
  }
}

}  // namespace nbv::bind
