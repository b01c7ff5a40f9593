# render/module.mk - seamtex-render, the CPU renderer that samples through seamtexd
# (docs/render.md). Included by the top Makefile.
#
# The dependency rule (ARCHITECTURE.md): render/ is a libseamtex client. Every render/ file is
# compiled with render/, client/, protocol/ and util/ headers only, so an #include of a store/
# or server/ header fails to compile; two files also see the store, on purpose:
# sampler_inproc.c (--inproc, the in-process baseline, as seamtex-bench's bench_inproc.c) and
# image_out.c (PNG through the store's OpenImageIO writer, reused rather than written twice).
$(B)/render/%.o:              MODINC := -Irender -Iclient -Iprotocol $(INC_util)
$(B)/render/sampler_inproc.o: MODINC := -Irender -Iclient -Iprotocol $(INC_STORE)
$(B)/render/image_out.o:      MODINC := -Irender -Iclient -Iprotocol $(INC_STORE)

# librender.a: everything but main.c (the tests link it)
RENDER_SRC := $(filter-out render/main.c,$(sort $(wildcard render/*.c)))
LIB_RENDER := $(B)/librender.a
$(LIB_RENDER): $(RENDER_SRC:%.c=$(B)/%.o)
	@mkdir -p $(@D)
	rm -f $@ && ar rcs $@ $^

$(B)/seamtex-render: $(B)/render/main.o $(LIB_RENDER) $(LIB_CLIENT) $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $(B)/render/main.o $(LIB_RENDER) $(LIB_CLIENT) $(LIB_STORE) $(LDLIBS)

ALL_BINS     += $(B)/seamtex-render
INSTALL_BINS += $(B)/seamtex-render
