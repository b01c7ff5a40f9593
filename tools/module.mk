# tools/module.mk - developer and report tools. Included by the top Makefile.

# ---- seamtex-seamreport (owner: BC1 / seam masking) ----
# The measured seam report of BC1 compression (tools/seamreport.c); close-ups in build/report/.
$(B)/tools/%.o: MODINC := $(INC_STORE)
$(B)/seamtex-seamreport: $(B)/tools/seamreport.o $(LIB_STORE)
	@mkdir -p $(@D)
	$(CC) $(LDFLAGS) -o $@ $< $(LIB_STORE) $(LDLIBS)
ALL_BINS += $(B)/seamtex-seamreport

# Generator of store/bc1/bc1_tables.h (run by hand, output checked in; not part of `all`).
$(B)/tools/bc1_gentables: tools/bc1_gentables.c
	@mkdir -p $(@D)
	$(CC) $(CFLAGS) -o $@ $<
