# python/module.mk - the Python module `seamtex` (a CPython extension over libseamtex), built
# into $(B)/python/seamtex/ so that tests import it from the build tree
# (PYTHONPATH=$(B)/python). Included by the top Makefile.
#
#   make python     the extension and the package files; part of `make all` when Debian's
#                   python3-dev headers exist for $(PYTHON3) (else skipped with a note)
#
# Built against Debian's interpreter (/usr/bin/python3, python3-dev), not whatever `python3`
# comes first on PATH. The extension's own objects see client/ and protocol/ headers (like
# libseamtex's clients) plus Python's (-isystem: its headers are not ours to warn about), and
# link libseamtex.a, which bundles the protocol and util objects. Not built with SAN=1 (the
# interpreter is not sanitised). `pip install --no-build-isolation ./python` builds the same
# sources through python/setup.py instead.

PYTHON3       ?= /usr/bin/python3
PY_INC        := $(shell $(PYTHON3) -c 'import sysconfig; print(sysconfig.get_paths()["include"])' 2>/dev/null)
PY_EXT_SUFFIX := $(shell $(PYTHON3) -c 'import sysconfig; print(sysconfig.get_config_var("EXT_SUFFIX"))' 2>/dev/null)
PY_HAVE       := $(if $(PY_INC),$(wildcard $(PY_INC)/Python.h))

PY_SRC   := $(sort $(wildcard python/seamtex/*.c))
PY_OBJ   := $(PY_SRC:python/seamtex/%.c=$(B)/pyobj/%.o)
PY_PKG   := $(B)/python/seamtex
PY_EXT   := $(PY_PKG)/_seamtex$(PY_EXT_SUFFIX)
PY_FILES := $(patsubst python/seamtex/%,$(PY_PKG)/%,\
              $(wildcard python/seamtex/*.py python/seamtex/*.pyi python/seamtex/py.typed))

$(B)/pyobj/%.o: python/seamtex/%.c
	@mkdir -p $(@D)
	$(CC) $(CPPFLAGS) -Iclient -Iprotocol -isystem $(PY_INC) $(CFLAGS) -fvisibility=hidden -c $< -o $@

$(PY_EXT): $(PY_OBJ) $(LIB_CLIENT)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -shared -o $@ $(PY_OBJ) $(LIB_CLIENT) -lm -lpthread

$(PY_PKG)/%: python/seamtex/%
	@mkdir -p $(@D)
	cp $< $@

ifeq ($(SAN)$(if $(PY_HAVE),yes,no),0yes)
python: $(PY_EXT) $(PY_FILES)
ALL_BINS += $(PY_EXT) $(PY_FILES)
else ifeq ($(SAN),1)
python:
	@echo "make python: not built with SAN=1 (the interpreter is not sanitised)"
else
python:
	@echo "make python: skipped: no Python.h for $(PYTHON3) (Debian: apt-get install python3-dev)"
all: python
endif
.PHONY: python
