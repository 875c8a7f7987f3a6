# A multi-part stereo EXR whose parts cover different data windows of one 8x6 display
# window, as OpenEXR's own multi-part samples do: a left RGBA part, a right RGBA part and a
# left depth part. Usage: python multipart_windows.py OUT.exr BUMP (BUMP is added to one red
# value of the right part, at display pixel (3, 3)). Needs OpenImageIO's Python module.
import OpenImageIO as oiio, sys, numpy as np
name, bump = sys.argv[1], float(sys.argv[2])
def spec(view, chans, x, y, w, h):
    s = oiio.ImageSpec(w, h, len(chans), "float")
    s.x, s.y = x, y
    s.full_x, s.full_y, s.full_width, s.full_height = 0, 0, 8, 6
    s.channelnames = tuple(chans)
    s.attribute("view", view)
    s.attribute("name", view + (".depth" if chans == ["Z"] else ".rgba"))
    return s
specs = [spec("left", ["R", "G", "B", "A"], 1, 0, 6, 6),
         spec("right", ["R", "G", "B", "A"], 0, 1, 8, 5),
         spec("left", ["Z"], 2, 2, 3, 3)]
out = oiio.ImageOutput.create(name)
assert out.open(name, specs), oiio.geterror()
for i, s in enumerate(specs):
    if i > 0:
        assert out.open(name, s, "AppendSubimage"), oiio.geterror()
    data = np.fromfunction(lambda y, x, c: (x + 2 * y + c + i) * 0.05,
                           (s.height, s.width, s.nchannels), dtype=np.float32)
    if i == 1:
        data[2, 3, 0] += bump
    assert out.write_image(data), out.geterror()
out.close()
